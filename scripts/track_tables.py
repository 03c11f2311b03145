#!/usr/bin/env python3
"""The README's `hvs track` tables, re-measured: static and moving spheres, two models.

Models (made here):
- `thesis-board`: `hvs simulate --case 3 --set train --postures grid --posture-levels
  2,2,2,2,2 --seed 1`, then `hvs train --hidden 12 --restarts 1` (the README's small model until
  2026-12-07). The thesis' 4 x 3 board in front of where the head looks: at every posture its
  pixels lie in the middle of the images (about u 291-346, v 228-247 of 640 x 480).
- `9x6-board`: the same postures with the 9 x 6 board at 6 cm (`--board 9x6:6`, 10,368 rows),
  the same training (the README's small model): its pixels span about u 201-439, v 167-306.

Scenes (case III, a 5 cm sphere of texture seed 2 before a wall at 300 cm; the scene files are
written here, so anyone can re-run them):
- static: the sphere at each centre, wall texture seeds 1 and 11, `--seconds 2 --seed 1`; the
  error after 1 s (median / worst over the frames and the two walls, px), the estimate (median
  z) against the sphere's surface (centre z minus 5 cm), and the frames whose target is the
  sphere (the log's error columns filled) and those whose target is something else.
- moving: 20 cm/s and the like, wall texture seed 1, `--seconds 3 --seed 1`; over t >= 0.5 s the
  median and 95th percentile error (px) and the frames on the sphere and off it.

Usage: python3 scripts/track_tables.py [--hvs target/release/hvs] [--keep DIR]
"""
import argparse
import csv
import json
import os
import statistics
import subprocess
import tempfile

STATIC = [
    (20, -8, 100), (-30, 10, 80), (0, 0, 60), (-34, 0, 60), (25, 12, 120),
    (-50, 15, 140), (40, 5, 150), (-60, -20, 180), (10, -15, 200),
]
MOVING = [
    ((-30, 0, 100), (20, 0, 0)), ((25, 8, 95), (-20, 0, 0)), ((-20, -10, 110), (18, 8, 0)),
    ((15, 5, 85), (-20, -3, 0)), ((-25, 0, 120), (20, 0, 0)), ((-10, 8, 105), (20, -4, 0)),
]


def run(cmd):
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def scene(path, centre, velocity, wall):
    s = {"rig": {"case": 3}, "camera_fps": 30,
         "background": {"z_cm": 300, "texture_seed": wall},
         "objects": [{"shape": "sphere", "radius_cm": 5, "centre_cm": list(centre),
                      "velocity_cm_s": list(velocity), "texture_seed": 2}]}
    with open(path, "w") as f:
        json.dump(s, f)


def log(hvs, model, scene_path, seconds, out):
    run([hvs, "track", "--model", model, "--scene", scene_path, "--seconds", str(seconds),
         "--log", out, "--seed", "1"])
    with open(out) as f:
        return list(csv.DictReader(f))


def pct(v, q):
    v = sorted(v)
    return v[min(len(v) - 1, int(round(q * (len(v) - 1))))]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--hvs", default="target/release/hvs")
    ap.add_argument("--keep")
    a = ap.parse_args()
    hvs = os.path.abspath(a.hvs)
    d = a.keep or tempfile.mkdtemp()
    os.makedirs(d, exist_ok=True)
    models = {}
    for name, extra in [("thesis-board", []), ("9x6-board", ["--board", "9x6:6"])]:
        data, model = os.path.join(d, f"{name}.csv"), os.path.join(d, f"{name}.hvsw")
        run([hvs, "simulate", "--case", "3", "--set", "train", "--postures", "grid",
             "--posture-levels", "2,2,2,2,2", "--seed", "1", "-o", data] + extra)
        run([hvs, "train", "--data", data, "-o", model, "--hidden", "12", "--restarts", "1"])
        models[name] = model
    print("static (2 s, after 1 s: err median/worst left, right px; median z vs surface; of 120 frames, those tracking the sphere and those tracking something else)")
    print("| sphere centre (cm) | " + " | ".join(models) + " |")
    print("|---|" + "---|" * len(models))
    for c in STATIC:
        cells = []
        for name, model in models.items():
            el, er, zs, on, off = [], [], [], 0, 0
            for wall in (1, 11):
                p = os.path.join(d, "s.json")
                scene(p, c, (0, 0, 0), wall)
                rows = log(hvs, model, p, 2, os.path.join(d, "s.csv"))
                on += sum(r["status"] == "tracking" and r["err_l_px"] != "" for r in rows)
                off += sum(r["status"] == "tracking" and r["err_l_px"] == "" for r in rows)
                for r in rows:
                    if float(r["t_s"]) >= 1.0 and r["err_l_px"]:
                        el.append(float(r["err_l_px"]))
                        er.append(float(r["err_r_px"]))
                    if float(r["t_s"]) >= 1.0 and r["err_l_px"] and r["z"]:
                        zs.append(float(r["z"]))
            if el:
                cells.append(
                    f"{statistics.median(el):.2f}/{max(el):.2f}, {statistics.median(er):.2f}/{max(er):.2f}; "
                    f"z {statistics.median(zs):.1f} vs {c[2] - 5}; {on} on it, {off} off")
            else:
                cells.append(f"never on the sphere; {off} frames on something else")
        print(f"| {c} | " + " | ".join(cells) + " |")
    print()
    print("moving (3 s, t >= 0.5 s: err median left/right, 95th percentile left/right px; of 90 frames, those tracking the sphere and those tracking something else)")
    print("| sphere centre at t = 0, velocity (cm, cm/s) | " + " | ".join(models) + " |")
    print("|---|" + "---|" * len(models))
    for c, v in MOVING:
        cells = []
        for name, model in models.items():
            p = os.path.join(d, "m.json")
            scene(p, c, v, 1)
            rows = log(hvs, model, p, 3, os.path.join(d, "m.csv"))
            on = sum(r["status"] == "tracking" and r["err_l_px"] != "" for r in rows)
            off = sum(r["status"] == "tracking" and r["err_l_px"] == "" for r in rows)
            el = [float(r["err_l_px"]) for r in rows if float(r["t_s"]) >= 0.5 and r["err_l_px"]]
            er = [float(r["err_r_px"]) for r in rows if float(r["t_s"]) >= 0.5 and r["err_r_px"]]
            if el:
                cells.append(f"{statistics.median(el):.2f}/{statistics.median(er):.2f}, "
                             f"{pct(el, 0.95):.2f}/{pct(er, 0.95):.2f}; {on} on it, {off} off")
            else:
                cells.append(f"never on the sphere; {off} frames on something else")
        print(f"| {c}, {v} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
