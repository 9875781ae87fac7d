"""`frictionuq simulate --params P.json --input X.csv --out F.csv`: the library result, written
atomically; bad parameters or records refused with one line, exit code 2, F.csv untouched."""
import json

import numpy as np
import pytest

import frictionuq as fq
from frictionuq.cli import main
from frictionuq.published import brfd_params


@pytest.fixture
def files(tmp_path):
    t = np.arange(2000) / 100.0
    x = 0.02 * np.sin(2 * np.pi * 0.2 * t)
    a = 100 + 5 * np.sin(t)
    X = tmp_path / "X.csv"
    X.write_text("time,displacement,applied\n" + "\n".join(f"{float(u)!r},{float(v)!r},{float(w)!r}" for u, v, w in zip(t, x, a)))
    P = tmp_path / "P.json"
    p = brfd_params(133.0)
    p["effects"] = {"reversal_hump": {"a_hump": 0.2, "l_hump": 3e-3}, "applied_tracking": {"beta_app": 0.8}}
    P.write_text(json.dumps(p))
    return t, x, a, X, P, tmp_path / "F.csv"


@pytest.mark.parametrize("model", ["three_stage", "lugre"])
def test_simulate_matches_library(files, capsys, model):
    t, x, a, X, P, F = files
    argv = ["simulate", "--params", str(P), "--input", str(X), "--out", str(F), "--model", model, "--eps", "1e-6"]
    effects = {"reversal_hump": {"a_hump": 0.2, "l_hump": 3e-3}, "applied_tracking": {"beta_app": 0.8}}
    assert main(argv) == 0
    out = np.loadtxt(F, delimiter=",", skiprows=1)
    assert open(F).readline().strip() == "time,displacement,force"
    ref = fq.simulate(t, x, brfd_params(133.0), effects=effects, model=model, eps=1e-6, applied=a)
    np.testing.assert_allclose(out[:, 0], t)
    np.testing.assert_allclose(out[:, 2], ref, rtol=1e-11, atol=1e-9)
    assert "2000 samples" in capsys.readouterr().out
    meta = json.loads(F.with_name("F.csv.json").read_text())
    assert meta["package_version"] == fq.__version__ and meta["model"] == model and meta["eps_m"] == 1e-6
    assert meta["effects"]["applied_tracking"] == {"beta_app": 0.8} and len(meta["input_sha256"]) == 64


def test_simulate_takes_the_fits_reversal_rule(files):
    """--reversal extreme re-simulates as `fit` does on measured records (its default rule): the
    library's result with that rule, recorded in the sidecar; with eps > 0 it differs from the
    spec's causal 'detection' rule, the default."""
    t, x, a, X, P, F = files
    effects = {"reversal_hump": {"a_hump": 0.2, "l_hump": 3e-3}, "applied_tracking": {"beta_app": 0.8}}
    base = ["simulate", "--params", str(P), "--input", str(X), "--eps", "1e-3"]
    assert main(base + ["--out", str(F), "--reversal", "extreme"]) == 0
    ref = fq.simulate(t, x, brfd_params(133.0), effects=effects, eps=1e-3, applied=a, reversal="extreme")
    np.testing.assert_allclose(np.loadtxt(F, delimiter=",", skiprows=1)[:, 2], ref, rtol=1e-11, atol=1e-9)
    assert json.loads(F.with_name("F.csv.json").read_text())["reversal"] == "extreme"
    D = F.with_name("D.csv")
    assert main(base + ["--out", str(D)]) == 0
    assert json.loads(D.with_name("D.csv.json").read_text())["reversal"] == "detection"
    assert np.max(np.abs(np.loadtxt(D, delimiter=",", skiprows=1)[:, 2] - ref)) > 100.0


def _edit(P, **changes):
    d = json.loads(P.read_text())
    for k, v in changes.items():
        if v is None:
            d.pop(k)
        else:
            d[k] = v
    P.write_text(json.dumps(d))


@pytest.mark.parametrize("edit,fragments", [
    (dict(fc_fwdd=1.0), ["P.json", "unknown parameter 'fc_fwdd'"]),
    (dict(sigma0=None), ["P.json", "missing parameter 'sigma0'"]),
    (dict(v_s=-1.0), ["P.json", "'v_s'", "-1 m/s is outside its physical bounds"]),
    (dict(effects={"thermal_fade": {"kappa": 2.0, "e_fade": 100.0}}),
     ["P.json", "'kappa': 2 is outside its physical bounds [0, 0.999]"]),   # no unit "1"
    (dict(k2="stiff"), ["P.json", "key k2", "expected a number"]),
    (dict(effects={"hump": {}}), ["P.json", "unknown effect 'hump'"]),
    (dict(effects={"reversal_hump": {"a_hmp": 1}}), ["P.json", "no parameter 'a_hmp'"]),
])
def test_bad_params(files, capsys, edit, fragments):
    t, x, a, X, P, F = files
    F.write_text("keep me\n")
    _edit(P, **edit)
    code = main(["simulate", "--params", str(P), "--input", str(X), "--out", str(F)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    for frag in fragments:
        assert frag in err, (frag, err)
    assert F.read_text() == "keep me\n"


def test_bad_input_record(files, capsys):
    t, x, a, X, P, F = files
    X.write_text("time,disp\n" + "\n".join(f"{u},{v}" for u, v in zip(t[:20], x[:20])))
    assert main(["simulate", "--params", str(P), "--input", str(X), "--out", str(F)]) == 2
    err = capsys.readouterr().err
    assert "X.csv" in err and "missing column 'displacement'" in err
    assert not F.exists()


def test_applied_tracking_needs_signal(files, capsys):
    t, x, a, X, P, F = files
    X.write_text("time,displacement\n" + "\n".join(f"{float(u)!r},{float(v)!r}" for u, v in zip(t, x)))
    assert main(["simulate", "--params", str(P), "--input", str(X), "--out", str(F)]) == 2
    assert "applied_tracking" in capsys.readouterr().err
    assert not F.exists()


def test_bad_json(files, capsys):
    t, x, a, X, P, F = files
    P.write_text("{not json")
    assert main(["simulate", "--params", str(P), "--input", str(X), "--out", str(F)]) == 2
    assert "not valid JSON" in capsys.readouterr().err
    # a parameter given twice: json keeps the last silently (until 2026-12-05 simulated so)
    P.write_text('{"fc_fwd": 100.0, "fc_fwd": 1000.0}')
    assert main(["simulate", "--params", str(P), "--input", str(X), "--out", str(F)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{P}, key fc_fwd: given twice" in err, err
    assert not F.exists()


@pytest.mark.parametrize("out", ["X.csv", "P.json", "P"])
def test_out_that_would_replace_an_input_is_refused(files, capsys, out):
    """--out (or its .json sidecar) naming --input or --params replaced the user's file (a new
    user's trial, 2026-12-05); refused, both inputs untouched."""
    t, x, a, X, P, F = files
    before = X.read_bytes(), P.read_bytes()
    assert main(["simulate", "--params", str(P), "--input", str(X), "--out", str(F.parent / out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "would replace an input file" in err, err
    assert (X.read_bytes(), P.read_bytes()) == before
