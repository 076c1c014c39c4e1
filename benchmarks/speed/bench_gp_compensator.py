"""The GP compensator's hyperparameters: this code's likelihood against scikit-learn's, same run, same answer.

On the README job's data (series B of the bundled UR10 data, 300 calibration poses, seed 0; the named causes
the diagnosis finds there), the GP compensator's Gaussian processes are fitted two ways, in turn:

- ``casadical``: :meth:`casadical.compensators._gp.ResidualGP.fit` (the marginal likelihood and its gradient
  from the joints' squared distances, one Cholesky factor and its inverse per evaluation);
- ``scikit-learn``: :class:`sklearn.gaussian_process.GaussianProcessRegressor` with the same kernel, bounds,
  start, ``normalize_y`` and L-BFGS-B iterations (how fe55b8a fitted them).

Each is timed in CPU seconds of this process (median of ``--repeats``, alternating), and both hyperparameter
sets are then judged the same way: the compensator's held-out means on the calibration poses' folds and its
validation mean on the other 1,195 poses (they must agree: the same objective from the same start).

Usage::

    python benchmarks/speed/bench_gp_compensator.py              # about a minute
    python benchmarks/speed/bench_gp_compensator.py --repeats 9
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from casadical import calibrate, load_robot  # noqa: E402
from casadical.calibration import gp_compensator_data, gp_compensator_held_out, with_gp_compensator
from casadical.compensators import FIT_ITERATIONS, FIT_POSES, LENGTH_BOUNDS, ResidualGP  # noqa: E402
from casadical.data import Measurements  # noqa: E402
from casadical.diagnosis import joint_levers, schemes  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "problems" / "datasets" / "ur10-ipa"
#: the model the README job's diagnosis ends with before its GP compensator (docs/diagnosis.md)
SPEC = "kinematic+joint_compliance[2]+joint_periodic[1:15,2:8,2:17,3:3,3:17,5:21]+encoder_scale[2]"


def sklearn_fit(X: np.ndarray, Y: np.ndarray, seed: int = 0) -> ResidualGP:
    """The processes fitted by scikit-learn's regressor, as fe55b8a did."""
    from scipy.optimize import minimize
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

    rows = np.sort(np.random.default_rng(seed).permutation(len(X))[:FIT_POSES])

    def optimizer(obj, theta0, bounds):
        r = minimize(obj, theta0, method="L-BFGS-B", jac=True, bounds=bounds, options={"maxiter": FIT_ITERATIONS})
        return r.x, r.fun

    ls, sv, nv = [], [], []
    for a in range(3):
        kernel = (ConstantKernel(1.0, (1e-4, 1e2)) * RBF(np.ones(X.shape[1]), LENGTH_BOUNDS)
                  + WhiteKernel(0.5, (1e-4, 1.0)))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            k = GaussianProcessRegressor(kernel, normalize_y=True, optimizer=optimizer,
                                         random_state=seed).fit(X[rows], Y[rows, a]).kernel_
        ls.append(np.atleast_1d(k.k1.k2.length_scale))
        sv.append(k.k1.k1.constant_value)
        nv.append(k.k2.noise_level)
    std = Y.std(axis=0)
    return ResidualGP(X, Y, np.array(ls), np.array(sv), np.array(nv), Y.mean(axis=0), np.where(std > 0, std, 1.0))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    robot = load_robot("ur10")
    b = Measurements.read_csv(DATA / "series_b.csv", n_joints=6)
    idx = np.sort(np.random.default_rng(0).permutation(len(b))[:300])
    cal, val = b.subset(idx), b.subset(np.setdiff1d(np.arange(len(b)), idx))
    res = calibrate(robot, cal, SPEC, "lm", warn=False)
    X, Y, keep = gp_compensator_data(res, cal)
    ways = {"casadical": lambda: ResidualGP.fit(X[keep], Y[keep]),
            "scikit-learn": lambda: sklearn_fit(X[keep], Y[keep])}
    times: dict[str, list[float]] = {k: [] for k in ways}
    fits = {}
    for name, f in ways.items():         # warm-up (imports)
        fits[name] = f()
    for _ in range(args.repeats):
        for name, f in ways.items():
            t = time.process_time()
            fits[name] = f()
            times[name].append(time.process_time() - t)
    sch = schemes(cal.q, cal.rows, 5, 0, joint_levers(robot, cal))
    learnt = {None: np.flatnonzero(keep)}
    print(f"the GP compensator's hyperparameters on {int(keep.sum())} poses (README job, series B, 300 poses, seed 0), "
          f"{args.repeats} runs each, in turn")
    print("fit          | CPU s (median, min-max) | held-out mean random / time / joint (mm) | validation mean (mm)")
    for name, gp in fits.items():
        folds = gp_compensator_held_out({None: gp}, learnt, cal, Y, keep, sch)
        m = folds.means_mm(gp.max_std_ratio)
        v = with_gp_compensator(res, {None: gp}, cal, "").stats(val).mean_mm
        t = times[name]
        print(f"{name:<12} | {statistics.median(t):.3f} ({min(t):.3f}-{max(t):.3f})       | "
              + " / ".join(f"{m[k][1]:.4f}" for k in ("random", "time", "joint")) + f"           | {v:.4f}")
    ratio = statistics.median(a / s for a, s in zip(times["casadical"], times["scikit-learn"]))
    same = np.allclose(fits["casadical"].length_scales, fits["scikit-learn"].length_scales, rtol=1e-6)
    print(f"CPU ratio casadical / scikit-learn: {ratio:.2f} (median of the pairs); the same hyperparameters: {same}")


if __name__ == "__main__":
    main()
