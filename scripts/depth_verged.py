#!/usr/bin/env python3
"""`hvs depth` end to end through the thesis' verged cameras (issue 25's rendered goal).

For case III and case IV (640 x 480; IV's right focal length is 0.8 times the left one):

1. Training boards spread over the whole image: a 9 x 6 board with squares of Z/24 cm at
   Z = 70, 100, 140, 190, 250, 320 cm, its centre at X = -0.85, -0.42, 0, 0.42, 0.85 times Z
   and Y = -0.55, 0, 0.55 times Z (`hvs render`, `hvs board detect`), then `hvs train --seed 5`
   (whose default for a set over most of the image is 4-12-3: the thesis' 5 hidden units fit
   the middle of the image, not all of it; `--hidden N` here passes N). A model learns depth
   only where its training pixels were: boards in the middle alone give depth in the middle
   alone.
2. Two scenes before a wall at 300 cm (`hvs render --scene`, their truth with them): spheres
   and boxes, and slanted planes with a sphere (the scenes of `vision/tests/dense_scene.rs`).
3. `hvs depth` on each pair, scored against the truth: of the left pixels the right camera
   sees (4 px from the border kept out), the share returned, the share of those within 1 px
   of the true match, and the median of |Z - Z_true| / Z_true; and the model alone on the true
   matches of 20,000 of those pixels (`hvs predict`): the model's part of the depth error.

Nothing here is an oracle: the matcher gets the model and the images, as a user's head would.

With `--scenes`, other scene files instead of the two (`scripts/verged-scenes/`: twenty
scenes made for a check after the matcher's settings were chosen, see the README).

Usage: python3 scripts/depth_verged.py [--hvs target/release/hvs] [--hidden N] [--keep DIR]
       [--cases 3,4] [--scenes SCENE.json ...]
Needs numpy.
"""
import argparse
import json
import os
import subprocess
import tempfile

import numpy as np

from stereo_score import read_pfm

# The scenes of `vision/tests/dense_scene.rs`; their rig is set to each case.
SCENES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "vision", "tests",
                      "fixtures", "scenes")
DEPTHS = [70, 100, 140, 190, 250, 320]
XS = [-0.85, -0.42, 0.0, 0.42, 0.85]
YS = [-0.55, 0.0, 0.55]


def run(args, **kw):
    return subprocess.run(args, check=True, capture_output=True, text=True, **kw)


def train(hvs, case, work, hidden):
    rows, header, missed = [], None, 0
    for z in DEPTHS:
        square = max(2, round(z / 24))
        for i, fx in enumerate(XS):
            for j, fy in enumerate(YS):
                d = os.path.join(work, f"b{case}_{z}_{i}_{j}")
                run([hvs, "render", "--case", str(case), "--depths", str(z), "--centre",
                     f"{round(fx * z)},{round(fy * z)}", "--inner-corners", "9x6",
                     "--square-cm", str(square), "-o", d, "--seed", str(z)])
                out = d + ".csv"
                got = subprocess.run([hvs, "board", "detect", "--board",
                                      os.path.join(d, "board.json"), "--captures",
                                      os.path.join(d, "captures.csv"), "-o", out],
                                     capture_output=True, text=True)
                if got.returncode != 0:
                    # The board not found in one of the images (e.g. its far corner outside
                    # the right camera's view): the pair is left out, as a user would.
                    missed += 1
                    continue
                with open(out) as f:
                    lines = f.read().splitlines()
                header = lines[0]
                rows += lines[1:]
    data = os.path.join(work, f"train{case}.csv")
    with open(data, "w") as f:
        f.write("\n".join([header] + rows) + "\n")
    model = os.path.join(work, f"m{case}.hvsw")
    run([hvs, "train", "--data", data, "-o", model, "--seed", "5"]
        + (["--hidden", str(hidden)] if hidden else []))
    topology = [line.split()[1] for line in run([hvs, "info", model]).stdout.splitlines()
                if line.startswith("topology:")][0]
    return model, len(rows), missed, topology


def score(hvs, model, pair):
    depth, matches = os.path.join(pair, "d.pfm"), os.path.join(pair, "m.pfm")
    said = run([hvs, "depth", "--model", model, "--left", os.path.join(pair, "left.png"),
                "--right", os.path.join(pair, "right.png"), "-o", depth,
                "--matches", matches]).stderr.strip().splitlines()[-1]
    z_true = read_pfm(os.path.join(pair, "depth.pfm"))[..., 0]
    truth = read_pfm(os.path.join(pair, "matches.pfm"))
    z, m = read_pfm(depth)[..., 0], read_pfm(matches)
    seen = truth[..., 2] > 0
    seen[:4], seen[-4:], seen[:, :4], seen[:, -4:] = False, False, False, False
    ret = seen & np.isfinite(m[..., 0])
    with np.errstate(invalid="ignore"):
        within = np.hypot(m[..., 0] - truth[..., 0], m[..., 1] - truth[..., 1])[ret] <= 1.0
    err = np.abs(z[ret] - z_true[ret]) / z_true[ret] * 100
    # The model alone on true matches.
    ys, xs = np.nonzero(seen)
    pick = np.random.default_rng(1).choice(len(xs), min(20000, len(xs)), replace=False)
    pts = os.path.join(pair, "true.csv")
    with open(pts, "w") as f:
        f.write("u_l,v_l,u_r,v_r\n")
        for k in pick:
            y, x = ys[k], xs[k]
            f.write(f"{x},{y},{float(truth[y, x, 0])!r},{float(truth[y, x, 1])!r}\n")
    out = run([hvs, "predict", "--model", model, "--points", pts]).stdout.splitlines()
    col = out[0].split(",").index("z")
    zp = np.array([float(r.split(",")[col]) for r in out[1:]])
    model_err = np.abs(zp - z_true[ys[pick], xs[pick]]) / z_true[ys[pick], xs[pick]] * 100
    return (said, seen.sum(), 100 * ret.sum() / seen.sum(), 100 * within.mean(),
            np.median(err), np.median(model_err))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--hvs", default="target/release/hvs")
    ap.add_argument("--hidden", type=int, help="hidden units of the model (hvs train's default)")
    ap.add_argument("--keep", help="work in this folder and keep it")
    ap.add_argument("--cases", default="3,4", help="the cases, e.g. 4")
    ap.add_argument("--scenes", nargs="+", metavar="SCENE.json",
                    help="scene files instead of the tests' two (their rig set to each case), e.g. "
                         "scripts/verged-scenes/*.json")
    a = ap.parse_args()
    scenes = a.scenes or [os.path.join(SCENES, n + ".json")
                          for n in ("spheres_and_boxes", "slanted_planes")]
    hvs = os.path.abspath(a.hvs)
    with tempfile.TemporaryDirectory() as tmp:
        work = a.keep or tmp
        os.makedirs(work, exist_ok=True)
        for case in (int(c) for c in a.cases.split(",")):
            model, n, missed, topology = train(hvs, case, work, a.hidden)
            print(f"case {case}: a {topology} model trained on {n} board corners over the whole image "
                  f"({missed} of {len(DEPTHS) * len(XS) * len(YS)} board pairs not detected)")
            for path in scenes:
                name = os.path.splitext(os.path.basename(path))[0]
                with open(path) as f:
                    text = json.load(f)
                text["rig"] = {"case": case}
                text.setdefault("camera_fps", 30)
                tag = name.split("_")[0]
                scene = os.path.join(work, f"{tag}{case}.json")
                with open(scene, "w") as f:
                    json.dump(text, f)
                pair = os.path.join(work, f"{tag}{case}")
                run([hvs, "render", "--scene", scene, "-o", pair, "--seed", "9"])
                said, seen, returned, within, median, model_median = score(hvs, model, pair)
                print(f"  {name.replace('_', ' ')}: {said}")
                print(f"    {seen} pixels seen by both cameras: {returned:.2f} % returned, "
                      f"{within:.2f} % of them within 1 px, median depth error {median:.3f} % "
                      f"(the model on the true matches: {model_median:.3f} %)")


if __name__ == "__main__":
    main()
