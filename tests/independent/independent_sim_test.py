#!/usr/bin/python3
"""msmcal on a folder of the independent simulator (indep_sim.py, README.md here).

usage: independent_sim_test.py MSMCAL WORK_DIR

Renders one folder of the issue 15 shape (1600 x 1200 BGR, 17 x 12 world board, 9 x 6 sliding
board on a larger plate with the spots beside it, saturated spots of sigma 1.3 px, three
triggers per scan frame, a 30 deg fan), runs `msmcal solve` and `msmcal hall calibrate` with
their defaults, and checks the result against the simulator's truth: every trigger's plane,
plane normals and beam directions within the stated tolerances, delta_t within 0.05 ms.
"""
import json
import os
import shutil
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import compare  # noqa: E402

# Tolerances: issue 15's goal is 0.020 deg for the normals; on this folder the solve gives
# 0.018 deg (seed 1; other draws of this simulator 0.008-0.035 deg, docs/solver.md), so the
# test allows 0.040 deg, 0.030 deg for a beam and the 0.05 ms for delta_t.
MAX_NORMAL_RMS_DEG = 0.040
MAX_BEAM_DEG = 0.030
MAX_DT_ERR_MS = 0.05


def run(cmd, log):
    with open(log, "w") as f:
        r = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT)
    if r.returncode != 0:
        sys.stdout.write(open(log).read()[-4000:])
        raise SystemExit("FAILED: %s exited %d" % (" ".join(cmd), r.returncode))
    return open(log).read()


def main():
    msmcal, work = sys.argv[1], sys.argv[2]
    folder = os.path.join(work, "medium_multi")
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    run(["/usr/bin/python3", os.path.join(HERE, "indep_sim.py"), folder, "--angle", "medium",
         "--trigger", "multi", "--seed", "1"], os.path.join(work, "render.log"))
    solve = run([msmcal, "solve", folder], os.path.join(work, "solve.log"))
    print(solve[-1500:])
    summary = json.load(open(os.path.join(folder, "results", "summary.json")))
    notes = " ".join(summary.get("mirror_poses", {}).get("notes", []))
    # The spots lie beside the sliding board, beyond its default margin: the solve says it took
    # the plate's whole plane.
    if "step 1: the listed dots lie beyond step1_dot_margin_squares" not in notes:
        raise SystemExit("FAILED: no note on the widened step 1 margin in summary.json")
    run([msmcal, "hall", "calibrate", folder], os.path.join(work, "hall.log"))
    out = compare.main(folder, as_json=False)
    failures = []
    if out.get("missing_triggers"):
        failures.append("triggers without a plane: %s" % out["missing_triggers"])
    if not out["normal_err_deg"]["rms"] <= MAX_NORMAL_RMS_DEG:
        failures.append("plane normals %.4f deg RMS > %.3f" % (out["normal_err_deg"]["rms"],
                                                              MAX_NORMAL_RMS_DEG))
    for b, v in sorted(out["beams"].items()):
        if not v["sign_ok"] or not v["dir_err_deg"] <= MAX_BEAM_DEG:
            failures.append("beam %s: %.4f deg (sign ok: %s)" % (b, v["dir_err_deg"], v["sign_ok"]))
    hall = out.get("hall") or {}
    if hall.get("err_ms") is None or not abs(hall["err_ms"]) <= MAX_DT_ERR_MS:
        failures.append("delta_t: %s" % hall)
    if failures:
        raise SystemExit("FAILED: " + "; ".join(failures))
    print("independent simulator: normals %.4f deg RMS, worst beam %.4f deg, delta_t off by "
          "%.4f ms" % (out["normal_err_deg"]["rms"],
                       max(v["dir_err_deg"] for v in out["beams"].values()), hall["err_ms"]))


if __name__ == "__main__":
    main()
