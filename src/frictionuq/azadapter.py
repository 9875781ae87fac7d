"""The one module that calls ArviZ (1.x: arviz_base, arviz_stats, arviz_plots).

Everything else in frictionuq passes plain numpy arrays here and gets xarray DataTrees, pandas
tables or figures back, so an ArviZ API change touches this file only. ArviZ is imported lazily
(about 3 s) inside the functions.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def build(posterior: dict, *, sample_stats: dict | None = None, log_likelihood: dict | None = None,
          observed_data: dict | None = None, posterior_predictive: dict | None = None,
          constant_data: dict | None = None, dims: dict | None = None, coords: dict | None = None,
          attrs: dict | None = None):
    """DataTree from arrays shaped (chain, draw, ...) (observed/constant data without them)."""
    import arviz_base as azb
    groups = {"posterior": posterior}
    for name, g in (("sample_stats", sample_stats), ("log_likelihood", log_likelihood),
                    ("observed_data", observed_data), ("posterior_predictive", posterior_predictive),
                    ("constant_data", constant_data)):
        if g:
            groups[name] = g
    import warnings
    with warnings.catch_warnings():
        # 16 independent chains of a short (capped) run have fewer draws than chains: expected
        # here, and said by the fit's convergence record, not by a warning on every run
        warnings.filterwarnings("ignore", message="Found chain dimension to be longer than draw")
        dt = azb.from_dict(groups, dims=dims or {}, coords=coords or {})
    for k, v in (attrs or {}).items():
        dt.attrs[k] = v if isinstance(v, (str, int, float)) else json.dumps(v, default=str)
        dt["posterior"].attrs[k] = dt.attrs[k]
    return dt


def save(dt, path) -> Path:
    """Write a DataTree to netCDF atomically (temporary file, then rename)."""
    from .atomic import replacing
    with replacing(path) as tmp:
        dt.to_netcdf(str(tmp), engine="h5netcdf")
    return Path(path)


def load(path):
    import xarray as xr
    return xr.open_datatree(str(path), engine="h5netcdf").load()


#: tail-ESS quantiles: the 5 % and 95 % of Vehtari et al. (2021). ArviZ 1.x's own default ties them
#: to its ci_prob (0.89: the 5.5 % and 94.5 % quantiles), which gives a larger tail ESS
TAIL_PROB = (0.05, 0.95)


def summary(dt, var_names=None):
    """Per-parameter table: mean, sd, q2.5, q97.5, r_hat, ess_bulk, ess_tail (raw floats); the
    tail ESS at TAIL_PROB, as `diagnostics` (the sampler's stopping rule) computes it."""
    import arviz_stats as azs
    s = azs.summary(dt, var_names=var_names, kind="all", round_to="none", ci_prob=0.95, ci_kind="eti")
    lb = [c for c in s.columns if c.endswith("_lb")][0]
    ub = [c for c in s.columns if c.endswith("_ub")][0]
    s = s.rename(columns={lb: "q2.5", ub: "q97.5"})
    tail = azs.ess(dt, var_names=var_names, method="tail", prob=TAIL_PROB)     # the posterior group
    s["ess_tail"] = [float(_select(tail, str(name))) for name in s.index]
    return s[["mean", "sd", "q2.5", "q97.5", "r_hat", "ess_bulk", "ess_tail"]]


def _select(ds, label: str):
    """One value of a Dataset by a summary row label: "name" or "name[coord]" (a variable with
    one dimension of its own, e.g. sigma_noise per test)."""
    name, _, rest = label.partition("[")
    da = ds[name]
    return da.sel({da.dims[0]: rest[:-1]}).values if rest else da.values


def diagnostics(samples: np.ndarray) -> dict:
    """R-hat (rank-normalised, split) and bulk/tail ESS of samples shaped (chain, draw, param)."""
    from arviz_stats.base import array_stats
    a = np.moveaxis(np.asarray(samples, float), 2, 0)          # (param, chain, draw)
    return {"r_hat": np.asarray(array_stats.rhat(a, chain_axis=-2, draw_axis=-1)),
            "ess_bulk": np.asarray(array_stats.ess(a, chain_axis=-2, draw_axis=-1, method="bulk")),
            "ess_tail": np.asarray(array_stats.ess(a, chain_axis=-2, draw_axis=-1, method="tail",
                                                   prob=TAIL_PROB))}


def psis_loo_units(log_lik: np.ndarray):
    """PSIS-LOO over units (e.g. whole tests): log_lik (chain, draw, unit) -> (elpd per unit,
    pareto k per unit). Used to screen before exact refits; see infer.compare."""
    import arviz_base as azb
    import arviz_stats as azs
    dt = azb.from_dict({"posterior": {"_": np.zeros(log_lik.shape[:2])},
                        "log_likelihood": {"y": log_lik}}, dims={"y": ["unit"]})
    res = azs.loo(dt, pointwise=True)
    return np.asarray(res.elpd_i).ravel(), np.asarray(res.pareto_k).ravel()


def _plot_few_chains(kind: str, dt, var_names, path, max_chains: int):
    """An arviz_plots figure of the first `max_chains` chains (emcee walkers are many; all of
    them crowd the plot), saved to `path`."""
    import arviz_plots as azp
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    sub = dt.sel(chain=slice(0, max_chains))
    pc = getattr(azp, kind)(sub, var_names=var_names, backend="matplotlib")
    pc.savefig(str(path))
    plt.close("all")
    return path


def rank_plot(dt, var_names, path, max_chains: int = 8):
    return _plot_few_chains("plot_rank", dt, var_names, path, max_chains)


def trace_plot(dt, var_names, path, max_chains: int = 8):
    return _plot_few_chains("plot_trace", dt, var_names, path, max_chains)


def rank_figure(dt, var_names, max_chains: int = 8):
    """The rank plot of `rank_plot` as a matplotlib Figure with a legend of the chains, for a
    caller that titles, sizes, saves and closes it itself (frictionuq.report)."""
    import arviz_plots as azp
    import matplotlib
    matplotlib.use("Agg")
    sub = dt.sel(chain=slice(0, max_chains - 1))
    # the simulated envelope on thinned draws (method "envelope"), not the default multi-chain
    # test (mtc_c): that test assumes independent draws and read p = 0.00 on every parameter of
    # a chain's autocorrelated stored draws, even those that passed R-hat
    pc = azp.plot_rank(sub, var_names=var_names, backend="matplotlib", method="envelope")
    pc.add_legend("chain")
    return pc.get_viz("figure")
