#!/usr/bin/env python3
"""`hvs track` on random scenes through the thesis' cameras: how often the sphere is held.

Each scene: a 5 cm sphere (random texture seed) at 70-160 cm, X within +-0.35 Z, Y within
+-0.2 Z, before a wall at 300 cm (random texture seed); half of them moving at 20 cm/s across
the view. The cases take turns. Models (made here, as the README's small model but on each
case's rig): `hvs simulate --case N --set train --board 9x6:6 --postures grid
--posture-levels 2,2,2,2,2 --seed 1`, then `hvs train --hidden 12 --restarts 1`.

Per scene: the frames whose target is the sphere (the log's error columns filled), those
tracking something else, and the median over t >= 0.5 s of the larger of the two image
errors (px). Per case: the scenes tracked at all and the frames on the sphere.

Usage: python3 scripts/track_random.py [--hvs target/release/hvs] [--seed 62] [--scenes 24]
       [--cases 2,3,4] [--seconds 2] [--keep DIR]
"""
import argparse
import csv
import json
import os
import random
import statistics
import subprocess
import tempfile


def run(cmd):
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--hvs", default="target/release/hvs")
    ap.add_argument("--seed", type=int, default=62)
    ap.add_argument("--scenes", type=int, default=24)
    ap.add_argument("--cases", default="2,3,4")
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--keep")
    a = ap.parse_args()
    hvs = os.path.abspath(a.hvs)
    d = a.keep or tempfile.mkdtemp()
    os.makedirs(d, exist_ok=True)
    cases = [int(c) for c in a.cases.split(",")]
    models = {}
    for c in cases:
        data, model = os.path.join(d, f"c{c}.csv"), os.path.join(d, f"c{c}.hvsw")
        if not os.path.exists(model):
            run([hvs, "simulate", "--case", str(c), "--set", "train", "--board", "9x6:6",
                 "--postures", "grid", "--posture-levels", "2,2,2,2,2", "--seed", "1", "-o", data])
            run([hvs, "train", "--data", data, "-o", model, "--hidden", "12", "--restarts", "1"])
        models[c] = model
    rng = random.Random(a.seed)
    tot = {c: [0, 0, 0, 0, 0] for c in cases}  # scenes, tracked, frames on, frames, off
    for k in range(a.scenes):
        case = cases[k % len(cases)]
        z = rng.uniform(70, 160)
        x = rng.uniform(-0.35, 0.35) * z
        y = rng.uniform(-0.2, 0.2) * z
        moving = rng.random() < 0.5
        v = [rng.choice([-20, 20]), rng.uniform(-5, 5), 0] if moving else [0, 0, 0]
        s = {"rig": {"case": case}, "camera_fps": 30,
             "background": {"z_cm": 300, "texture_seed": rng.randint(1, 50)},
             "objects": [{"shape": "sphere", "radius_cm": 5, "centre_cm": [x, y, z],
                          "velocity_cm_s": v, "texture_seed": rng.randint(1, 50)}]}
        p = os.path.join(d, f"s{k}.json")
        with open(p, "w") as f:
            json.dump(s, f)
        lg = os.path.join(d, f"s{k}.csv")
        run([hvs, "track", "--model", models[case], "--scene", p, "--seconds", str(a.seconds),
             "--log", lg, "--seed", "1"])
        with open(lg) as f:
            rows = list(csv.DictReader(f))
        on = [r for r in rows if r["status"] == "tracking" and r["err_l_px"] != ""]
        off = sum(r["status"] == "tracking" and r["err_l_px"] == "" for r in rows)
        err = [max(float(r["err_l_px"]), float(r["err_r_px"])) for r in on
               if float(r["t_s"]) >= 0.5]
        med = f"{statistics.median(err):.2f}" if err else "-"
        print(f"s{k} case {case}, ({x:.0f}, {y:.0f}, {z:.0f}) {'moving' if moving else 'static'}: "
              f"{len(on)}/{len(rows)} frames on the sphere, {off} on something else, "
              f"median err {med} px", flush=True)
        t = tot[case]
        t[0] += 1
        t[1] += len(on) > 0
        t[2] += len(on)
        t[3] += len(rows)
        t[4] += off
    for c, t in tot.items():
        print(f"case {c}: {t[1]} of {t[0]} scenes tracked, {t[2]} of {t[3]} frames on the "
              f"sphere, {t[4]} on something else")


if __name__ == "__main__":
    main()
