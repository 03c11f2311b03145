#!/usr/bin/env python3
"""`hvs depth` (the whole command) against OpenCV's StereoSGBM, side by side, in one run.

On Middlebury's Motorcycle pair (scikit-image's 741 x 500 copy; see
`vision/tests/dense_real.rs` for where to get it), with the issue's StereoSGBM settings:
3-way, block 5, P1 200, P2 800, uniqueness 10, speckle 100 / 2, left-right 1, on the grey
images, over the disparities `hvs depth` searches (its `lo..hi`, widened to a multiple of
16 as StereoSGBM needs).

- Time: `hvs depth --model M --left L --right R -o D.pfm` from process start to exit
  (decoding, matching, the model, writing), and StereoSGBM's two `cv2.imread` plus
  `compute` inside this process; the two alternate in one loop, medians of `--runs`. On one
  core (`RAYON_NUM_THREADS=1`, `cv2.setNumThreads(1)`) and on two threads.
- Accuracy, where the truth is at hand (`disp_741x500.f32` or `motorcycle_disp.npz` beside
  the images): as the issue scores it, every pixel with a truth whose match lies inside the
  right image: returned %, and of the returned the % more than 2 px and more than 1 px off.

Usage: python3 scripts/depth_vs_sgbm.py [--hvs target/release/hvs] [--dir /tmp/motorcycle]
       [--model M.hvsw] [--runs 11] [--thorough]
Without --model, one is trained on `host/tests/fixtures/motorcycle/train.csv` (seed 7, the
README's worked example). Needs numpy and OpenCV (`pip install opencv-python-headless`) and a
release build of hvs.
"""
import argparse
import os
import re
import statistics
import subprocess
import tempfile
import time

import cv2
import numpy as np

from stereo_score import rates, read_pfm

ap = argparse.ArgumentParser()
ap.add_argument("--hvs", default="target/release/hvs")
ap.add_argument("--dir", default=os.environ.get("HVS_MOTORCYCLE_DIR", "/tmp/motorcycle"))
ap.add_argument("--model")
ap.add_argument("--runs", type=int, default=11)
ap.add_argument("--thorough", action="store_true", help="time `hvs depth --thorough`")
a = ap.parse_args()

left = os.path.join(a.dir, "motorcycle_left.png")
right = os.path.join(a.dir, "motorcycle_right.png")
here = os.path.dirname(os.path.abspath(__file__))


def truth(h, w):
    raw = os.path.join(a.dir, "disp_741x500.f32")
    if os.path.exists(raw):
        return np.fromfile(raw, dtype="<f4").reshape(h, w)
    npz = os.path.join(a.dir, "motorcycle_disp.npz")
    if os.path.exists(npz):
        return np.load(npz)["arr_0"].astype(np.float32).reshape(h, w)
    return None


with tempfile.TemporaryDirectory() as tmp:
    model = a.model
    if model is None:
        model = os.path.join(tmp, "moto.hvsw")
        data = os.path.join(here, "..", "host", "tests", "fixtures", "motorcycle", "train.csv")
        subprocess.run([a.hvs, "train", "--data", data, "-o", model, "--seed", "7"],
                       check=True, capture_output=True)
    depth, matches = os.path.join(tmp, "d.pfm"), os.path.join(tmp, "m.pfm")
    cmd = [a.hvs, "depth", "--model", model, "--left", left, "--right", right, "-o", depth]
    cmd += ["--thorough"] if a.thorough else []
    said = subprocess.run(cmd + ["--matches", matches], check=True, capture_output=True,
                          text=True).stderr
    found = re.search(r"disparities (-?\d+)\.\.(-?\d+) px searched", said)
    if not found:
        raise SystemExit(f"hvs depth did not say its disparity range:\n{said}")
    lo, hi = int(found.group(1)), int(found.group(2))
    n_disp = -(-(hi - lo + 1) // 16) * 16
    sgbm = cv2.StereoSGBM_create(minDisparity=lo, numDisparities=n_disp, blockSize=5, P1=200,
                                 P2=800, disp12MaxDiff=1, uniquenessRatio=10,
                                 speckleWindowSize=100, speckleRange=2,
                                 mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)

    def sgbm_once():
        t = time.perf_counter()
        out = sgbm.compute(cv2.imread(left, cv2.IMREAD_GRAYSCALE),
                           cv2.imread(right, cv2.IMREAD_GRAYSCALE))
        return time.perf_counter() - t, out

    def hvs_once(env):
        t = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True, env=env)
        return time.perf_counter() - t

    print(f"Motorcycle 741x500, disparities {lo}..{hi} (StereoSGBM: {lo}..{lo + n_disp - 1}); "
          f"medians of {a.runs}, alternating")
    for threads in (1, 2):
        env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
        cv2.setNumThreads(threads)
        hvs_once(env)  # warm the page cache
        ours, theirs = [], []
        for _ in range(a.runs):
            ours.append(hvs_once(env))
            theirs.append(sgbm_once()[0])
        h, s = statistics.median(ours), statistics.median(theirs)
        print(f"{threads} thread(s): hvs depth {h * 1e3:.1f} ms, StereoSGBM {s * 1e3:.1f} ms: "
              f"hvs takes {h / s:.2f}x StereoSGBM's time")

    m = read_pfm(matches)
    gt = truth(*m.shape[:2])
    if gt is None:
        print("no truth beside the images: accuracy not scored")
    else:
        xs = np.arange(m.shape[1])[None, :]
        ur = m[:, :, 0]
        ours = rates(np.where(np.isfinite(ur), xs - ur, np.nan), np.isfinite(ur), gt)
        d16 = sgbm_once()[1]
        theirs = rates(d16.astype(np.float32) / 16, d16 > (lo - 1) * 16, gt)
        for name, (ret, off2, off1) in (("hvs depth", ours), ("StereoSGBM", theirs)):
            print(f"{name}: {ret:.2f} % returned; of those {off2:.2f} % more than 2 px off, "
                  f"{off1:.2f} % more than 1 px")
