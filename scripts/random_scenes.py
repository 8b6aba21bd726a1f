#!/usr/bin/python3
"""Randomised variants of the issue-15 "independent-like" scene, through the command line.

  scripts/random_scenes.py OUT_DIR SEED [SEED...]

For each seed: draws a scene (boards, camera, distortion, spots, colour, exposures, triggers per
frame, spanning angle; see draw()), writes OUT_DIR/r<seed>.sim.yaml, runs `msmcal simulate`,
`msmcal solve` and `msmcal hall calibrate` (logs beside the folder) and prints one line against
the simulator's truth: plane-normal RMS, worst beam direction, the session's dt and whether it was
identified, and the solve's wall time. Exit status 1 when any step failed. Uses build/app/msmcal
(scripts/build msmcal). Session 20 found two solver faults this way (README, "Images the solver
has been shown to handle").
"""
import csv
import math
import os
import random
import re
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MSMCAL = os.path.join(ROOT, "build", "app", "msmcal")


def draw(seed):
    r = random.Random(seed)
    sq, cols, rows = r.choice([(10, 25, 18), (12, 21, 14), (15, 17, 12), (20, 13, 10)])
    ssq, scols, srows = r.choice([(8, 11, 8), (10, 9, 6), (12, 7, 6), (10, 11, 6)])
    w, h = r.choice([(1600, 1200), (2048, 1536), (1280, 1024), (1920, 1200)])
    fx = r.uniform(0.7, 1.0) * w
    k1 = r.uniform(-0.15, 0.05)
    ang = r.uniform(15, 46)
    aimx, aimy = cols * sq * 0.45, rows * sq * 0.45
    far = fx / 1250 * 1600 / w  # keeps the boards' size in the image about the same
    return f"""seed: {seed}
mirror:
  slow:
    amplitude_vpp: {r.choice([2, 3, 4])}
geometry:
  board_aim_mm: [{aimx:.1f}, {aimy:.1f}]
  mirror_distance_mm: {r.choice([200, 230, 250])}
beams:
  spanning_angle_deg: {ang:.1f}
world_board:
  cols: {cols}
  rows: {rows}
  square_mm: {sq}
sliding_board:
  cols: {scols}
  rows: {srows}
  square_mm: {ssq}
camera:
  width: {w}
  height: {h}
  fx: {fx:.1f}
  fy: {fx * r.uniform(0.998, 1.002):.1f}
  cx: {w / 2 - 0.5 + r.uniform(-20, 20):.1f}
  cy: {h / 2 - 0.5 + r.uniform(-20, 20):.1f}
  distortion: [{k1:.3f}, {r.uniform(-0.05, 0.1):.3f}, 0, 0, 0]
  c1_centre_mm: [{-640 * far:.0f}, {aimy:.0f}, {-560 * far:.0f}]
  c1_target_mm: [60, {aimy:.0f}, -150]
  c2_centre_mm: [{aimx + 80:.0f}, {aimy + 8:.0f}, {-550 * far:.0f}]
  c2_target_mm: [{aimx:.0f}, {aimy:.0f}, 0]
render:
  dot_sigma_mm: {r.uniform(0.3, 1.2):.2f}
  dot_peak: {r.choice([0.3, 0.6, 1.0, 2.0, 1.5])}
  noise_sigma: {r.uniform(0.002, 0.01):.4f}
  colour: {r.choice(['true', 'false'])}
step1:
  exposures: {r.choice([1, 3])}
step2:
  scan_triggers_per_frame: {r.choice([1, 3])}
"""


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def angle_deg(a, b):
    c = sum(x * y for x, y in zip(a, b)) / math.sqrt(sum(x * x for x in a) * sum(y * y for y in b))
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def score(d):
    est = {r["j"]: r for r in rows(os.path.join(d, "results", "mirror_planes.csv"))}
    tru = {r["j"]: r for r in rows(os.path.join(d, "truth", "mirror_planes.csv"))}
    keys = ("nx", "ny", "nz")
    errs = []
    for j, r in est.items():
        if j in tru:
            e = angle_deg([float(r[k]) for k in keys], [float(tru[j][k]) for k in keys])
            errs.append(min(e, 180 - e))
    truth_beams = {r["beam"]: r for r in rows(os.path.join(d, "truth", "beams.csv"))}
    worst = 0.0
    for r in rows(os.path.join(d, "results", "beams.csv")):
        t = truth_beams.get(r["beam"])
        if t:
            worst = max(worst, angle_deg([float(r[k]) for k in ("vx", "vy", "vz")],
                                         [float(t[k]) for k in ("vx", "vy", "vz")]))
    with open(os.path.join(d, "results", "hall_model.yaml")) as f:
        hall = f.read()
    offset = hall[hall.find("time_offset:"):]
    dt = re.search(r"delta_t_s: ([-\d.e+]+)", offset)
    status = re.search(r"status: ([\w ]+)", offset)
    rms = math.sqrt(sum(e * e for e in errs) / len(errs)) if errs else float("nan")
    return (f"{len(errs)} planes, normals {rms:.4f} deg RMS, worst beam {worst:.4f} deg, "
            f"dt {float(dt.group(1)) * 1e3 if dt else float('nan'):.3f} ms "
            f"({status.group(1).strip() if status else '?'})")


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    failed = 0
    for seed in (int(s) for s in sys.argv[2:]):
        d = os.path.join(out, f"r{seed}")
        with open(d + ".sim.yaml", "w") as f:
            f.write(draw(seed))
        line = f"seed {seed}: "
        steps = [("simulate", [MSMCAL, "simulate", d, "--config", d + ".sim.yaml"]),
                 ("solve", [MSMCAL, "solve", d]), ("hall", [MSMCAL, "hall", "calibrate", d])]
        ok = True
        solve_s = 0.0
        for name, cmd in steps:
            t0 = time.monotonic()
            with open(f"{d}.{name}.log", "w") as log:
                rc = subprocess.call(cmd, stdout=log, stderr=subprocess.STDOUT)
            if name == "solve":
                solve_s = time.monotonic() - t0
            if rc != 0:
                with open(f"{d}.{name}.log") as log:
                    last = (log.read().strip().splitlines() or [""])[-1]
                line += f"{name} FAILED (exit {rc}): {last[-200:]}"
                ok = False
                break
        if ok:
            line += f"{score(d)}, solve {solve_s:.0f} s"
        else:
            failed += 1
        print(line, flush=True)
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
