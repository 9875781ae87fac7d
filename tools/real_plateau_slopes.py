"""How the sliding force of the real ARTS sine records varies with speed and with position
(docs/model-choices.md, `speed_weakening`). Per test and direction, well past the take-up
(travel since the reversal > 12 mm), least squares of the force on [1, |v|, x^2, x] (x from the
median): prints the plateau F0, the change over 0..peak |v| and over 0..peak |x| of the x^2 term,
and the residual sd of the fit with both, with |v| only and with x only. Displacement and force
are low-passed at 20 Hz (4th-order Butterworth, zero phase) before differencing.

    .venv/bin/python tools/real_plateau_slopes.py [CAMPAIGN]      (default: data/brfd-arts-d1)
"""
import sys

import numpy as np
from scipy.signal import butter, filtfilt

from frictionuq.campaign import load_campaign


def main(path="data/brfd-arts-d1"):
    for test in load_campaign(path).tests:
        r = test.record
        t, x, f = np.asarray(r.t), np.asarray(r.x), np.asarray(r.force)
        b, a = butter(4, 20.0 / (0.5 / np.median(np.diff(t))))
        xf, ff = filtfilt(b, a, x), filtfilt(b, a, f)
        v = np.gradient(xf, t)
        d = np.sign(v)
        s = np.zeros_like(x)
        acc = 0.0
        for k in range(1, x.size):
            if d[k] != d[k - 1]:
                acc = 0.0
            acc += abs(xf[k] - xf[k - 1])
            s[k] = acc
        xc = xf - np.median(xf)
        print(test.id)
        for sg, name in ((1, "fwd"), (-1, "bwd")):
            m = (s > 0.012) & (d == sg)
            y = sg * ff[m]
            X = np.column_stack([np.ones(m.sum()), np.abs(v[m]), xc[m] ** 2, xc[m]])

            def sd(cols):
                c, *_ = np.linalg.lstsq(X[:, cols], y, rcond=None)
                return c, (y - X[:, cols] @ c).std()
            c, r_all = sd([0, 1, 2, 3])
            _, r_v = sd([0, 1])
            _, r_x = sd([0, 2, 3])
            vm, xm = np.abs(v[m]).max(), np.abs(xc[m]).max()
            print(f"   {name} F0 {c[0] / 1e3:6.2f} kN   dF over |v| 0-{vm:.3f} m/s {c[1] * vm / 1e3:+6.2f} kN"
                  f"   dF over x^2 0-{xm * 1e3:.0f} mm {c[2] * xm ** 2 / 1e3:+6.2f} kN   residual sd "
                  f"(kN): both {r_all / 1e3:.2f}, |v| only {r_v / 1e3:.2f}, x only {r_x / 1e3:.2f}")


if __name__ == "__main__":
    main(*sys.argv[1:])
