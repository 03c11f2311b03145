#!/usr/bin/env python3
"""`hvs train` (the whole command) against scikit-learn's MLPRegressor, side by side.

The 72 integer-pixel board points of a case (`hvs simulate --case N --set train`):
- `hvs train --data SET -o M --seed S`, process start to exit, median of 5 runs;
- scikit-learn: inputs and targets standardised, MLPRegressor(hidden_layer_sizes=(5,),
  solver="lbfgs"), its other settings the defaults (ReLU, at most 200 iterations), 10
  restarts (random_state 0..9), the best kept: the whole fit, median of 3. Of the variants
  tried (ReLU or logistic, standardised or not), this is the one whose time matched the
  speed issue's 375-392 ms here (379 ms; logistic: 309 ms, unscaled logistic: 73 ms).
  scikit-learn 1.9.1 over numpy 2.4.6 (2026-12-05) fits the same in 161-183 ms.

Usage: python3 scripts/train_vs_sklearn.py [--hvs target/release/hvs] [--case 4] [--seed 0]
Needs: scikit-learn (pip install scikit-learn), a release build of hvs.
"""
import argparse
import csv
import os
import statistics
import subprocess
import tempfile
import time
import warnings

import numpy as np
from sklearn.exceptions import ConvergenceWarning
from sklearn.neural_network import MLPRegressor
from sklearn.preprocessing import StandardScaler

ap = argparse.ArgumentParser()
ap.add_argument("--hvs", default="target/release/hvs")
ap.add_argument("--case", type=int, default=4)
ap.add_argument("--seed", type=int, default=0)
a = ap.parse_args()

with tempfile.TemporaryDirectory() as tmp:
    data = os.path.join(tmp, "train.csv")
    subprocess.run([a.hvs, "simulate", "--case", str(a.case), "--set", "train", "-o", data],
                   check=True, capture_output=True)
    rows = list(csv.DictReader(open(data)))
    x = np.array([[float(r[k]) for k in ("u_l", "v_l", "u_r", "v_r")] for r in rows])
    y = np.array([[float(r[k]) for k in ("x", "y", "z")] for r in rows])

    def hvs_once():
        t = time.perf_counter()
        subprocess.run([a.hvs, "train", "--data", data, "-o", os.path.join(tmp, "m.hvsw"),
                        "--seed", str(a.seed)], check=True, capture_output=True)
        return time.perf_counter() - t

    def sklearn_once():
        t = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            sx, sy = StandardScaler().fit(x), StandardScaler().fit(y)
            xs, ys = sx.transform(x), sy.transform(y)
            best = None
            for rs in range(10):
                m = MLPRegressor(hidden_layer_sizes=(5,), solver="lbfgs",
                                 random_state=rs).fit(xs, ys)
                err = np.mean((m.predict(xs) - ys) ** 2)
                if best is None or err < best[0]:
                    best = (err, m)
        return time.perf_counter() - t

    hvs_once()  # warm the page cache
    h = statistics.median(hvs_once() for _ in range(5))
    s = statistics.median(sklearn_once() for _ in range(3))
    print(f"case {a.case}, {len(rows)} points: hvs train {h * 1e3:.1f} ms (median of 5), "
          f"scikit-learn {s * 1e3:.1f} ms (median of 3): {s / h:.1f}x")
