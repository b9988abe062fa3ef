#!/usr/bin/python3
"""scikit-learn reference for bench_gp_fit: fits GaussianProcessRegressor on the data the
bench hands over, with the same kernel, bounds, alpha and number of restarts, and times it.

Usage: bench/gp_fit_reference.py IN.json OUT.json
IN:  {"kernel": {initial, bounds, restarts, alpha}, "sets": [{"name", "x", "y_x", "y_y"}], "predict_points": 100}
OUT: {"sklearn": version, "sets": [{"name", "fit_s", "lml_x", "lml_y", "predict_ms"}]}
fit_s is the wall time of fitting both the x- and the y-GP; predict_ms the median time of
one 100-point predict(return_std=True) of the x-GP.
"""
import json
import sys
import time

import numpy as np
import sklearn
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel


def make(k):
    kernel = ConstantKernel(k["constant"], tuple(k["constant_bounds"])) * \
        RBF(k["length_scale"], tuple(k["length_scale_bounds"])) + \
        WhiteKernel(k["noise_level"], tuple(k["noise_bounds"]))
    return GaussianProcessRegressor(kernel=kernel, alpha=k["alpha"], normalize_y=False,
                                    n_restarts_optimizer=k["restarts"], random_state=0)


def main(argv):
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    with open(argv[1]) as f:
        spec = json.load(f)
    out = {"sklearn": sklearn.__version__, "sets": []}
    xq = np.linspace(0.0, 1.0, spec["predict_points"]).reshape(-1, 1)
    for s in spec["sets"]:
        x = np.asarray(s["x"]).reshape(-1, 1)
        t0 = time.perf_counter()
        gx = make(spec["kernel"]).fit(x, np.asarray(s["y_x"]))
        gy = make(spec["kernel"]).fit(x, np.asarray(s["y_y"]))
        fit_s = time.perf_counter() - t0
        times = []
        for _ in range(20):
            t0 = time.perf_counter()
            gx.predict(xq, return_std=True)
            times.append(time.perf_counter() - t0)
        out["sets"].append({"name": s["name"], "fit_s": fit_s,
                            "lml_x": float(gx.log_marginal_likelihood_value_),
                            "lml_y": float(gy.log_marginal_likelihood_value_),
                            "predict_ms": 1000 * float(np.median(times))})
        print("sklearn %s: %d samples, fit %.2f s" % (s["name"], len(s["x"]), fit_s), file=sys.stderr)
    with open(argv[2], "w") as f:
        json.dump(out, f)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
