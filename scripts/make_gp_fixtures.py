#!/usr/bin/python3
"""Writes the scikit-learn parity fixtures of the gp module: test/data/gp/sklearn_*.json.

Each fixture holds training data, the kernel set-up (ConstantKernel * RBF + WhiteKernel,
or RBF + WhiteKernel), bounds and restarts, and what scikit-learn's
GaussianProcessRegressor found: the optimised hyper-parameters, the log marginal
likelihood there and predictions (mean, std) at test inputs. test/unit/gp/test_sklearn_parity.cpp
reads them; the test itself needs no Python.

Run once (needs Debian's python3-sklearn):  scripts/make_gp_fixtures.py
"""
import json
import os
import sys

import numpy as np
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

OUT = os.path.join(os.path.dirname(os.path.realpath(__file__)), "..", "test", "data", "gp")


def make_kernel(spec):
    rbf = RBF(spec["initial"]["length_scale"], tuple(spec["length_scale_bounds"]))
    white = WhiteKernel(spec["initial"]["noise_level"], tuple(spec["noise_bounds"]))
    if spec["use_constant"]:
        return ConstantKernel(spec["initial"]["constant"], tuple(spec["constant_bounds"])) * rbf + white
    return rbf + white


def params_of(kernel, use_constant):
    p = kernel.get_params()
    if use_constant:
        return {"constant": p["k1__k1__constant_value"], "length_scale": p["k1__k2__length_scale"],
                "noise_level": p["k2__noise_level"]}
    return {"constant": 1.0, "length_scale": p["k1__length_scale"], "noise_level": p["k2__noise_level"]}


def write(name, x, y, x_test, spec, restarts, optimize=True):
    kernel = make_kernel(spec)
    gpr = GaussianProcessRegressor(kernel=kernel, alpha=1e-10, normalize_y=False,
                                   n_restarts_optimizer=restarts, random_state=0,
                                   optimizer="fmin_l_bfgs_b" if optimize else None)
    gpr.fit(x.reshape(-1, 1), y)
    mean, std = gpr.predict(x_test.reshape(-1, 1), return_std=True)
    fixture = dict(spec)
    fixture.update({
        "description": name,
        "restarts": restarts,
        "optimize": optimize,
        "alpha": 1e-10,
        "x": x.tolist(), "y": y.tolist(), "x_test": x_test.tolist(),
        "fitted": params_of(gpr.kernel_, spec["use_constant"]),
        "log_marginal_likelihood": float(gpr.log_marginal_likelihood_value_),
        "mean": mean.tolist(), "std": std.tolist(),
    })
    path = os.path.join(OUT, "sklearn_%s.json" % name)
    with open(path, "w") as f:
        json.dump(fixture, f, indent=1)
        f.write("\n")
    print("%s: LML %.6f, %s" % (path, fixture["log_marginal_likelihood"], fixture["fitted"]))


def main():
    os.makedirs(OUT, exist_ok=True)
    rng = np.random.RandomState(42)
    x_test = np.linspace(-0.05, 1.05, 23)
    base = {
        "use_constant": True,
        "initial": {"constant": 1.0, "length_scale": 0.3, "noise_level": 0.01},
        "constant_bounds": [1e-4, 1e2], "length_scale_bounds": [1e-2, 10.0], "noise_bounds": [1e-6, 1.0],
    }

    # Scattered distinct inputs, a smooth function with noise.
    x = np.sort(rng.uniform(0, 1, 40))
    y = np.sin(6 * x) + 0.05 * rng.randn(40)
    write("distinct", x, y, x_test, base, restarts=2)

    # Without the constant factor (the paper's plain RBF + WhiteKernel).
    plain = dict(base, use_constant=False)
    write("no_constant", x, y, x_test, plain, restarts=2)

    # A primitive's structure: 5 segments on the same 100 progress values (500 samples),
    # an arc whose amplitude varies a little from segment to segment.
    s = np.linspace(0, 1, 100)
    xs, ys = [], []
    for k in range(5):
        a = 0.3 * (1 + 0.05 * rng.uniform(-1, 1))
        xs.append(s)
        ys.append(a * np.sin(np.pi * s) + 0.002 * rng.randn(100))
    write("repeated", np.concatenate(xs), np.concatenate(ys), x_test, base, restarts=2)

    # Fixed hyper-parameters: predictions only (optimizer=None).
    fixed = dict(base, initial={"constant": 0.7, "length_scale": 0.15, "noise_level": 0.003})
    write("fixed", x, y, x_test, fixed, restarts=0, optimize=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
