#!/usr/bin/python3
"""Compare msmcal results (DIR/results) with the independent simulator's truth (DIR/truth).

usage: /usr/bin/python3 compare.py DIR [--json]
"""
import csv
import json
import math
import os
import sys

import numpy as np
import yaml


def read_csv(p):
    with open(p) as f:
        return list(csv.DictReader(f))


def ang(a, b):
    a = np.asarray(a, float) / np.linalg.norm(a)
    b = np.asarray(b, float) / np.linalg.norm(b)
    return math.degrees(math.atan2(np.linalg.norm(np.cross(a, b)), float(a @ b)))


def rms(x):
    x = np.asarray(x, float)
    return float(np.sqrt(np.mean(x ** 2))) if x.size else float("nan")


def main(d, as_json=False):
    res, tru = os.path.join(d, "results"), os.path.join(d, "truth")
    out = {"dir": d}
    T = {int(r["j"]): r for r in read_csv(os.path.join(tru, "mirror_planes.csv"))}
    f0 = yaml.safe_load(open(os.path.join(tru, "frame0.yaml")))
    R_W0 = np.array(f0["R_W0"], float)
    X_lsq_true = np.array(f0["origin_lsq_scan_planes"], float)
    p = os.path.join(res, "mirror_planes.csv")
    if not os.path.isfile(p):
        out["error"] = "no results/mirror_planes.csv"
        print(json.dumps(out) if as_json else out)
        return out
    E = {int(r["j"]): r for r in read_csv(p)}
    js = sorted(set(E) & set(T))
    out["planes"] = "%d of %d truth triggers estimated" % (len(js), len(T))
    out["missing_triggers"] = sorted(set(T) - set(E))
    en, ed, ea, eb, et, et_lsq, sa, sb, st = [], [], [], [], [], [], [], [], []
    nt_all = np.array([[float(T[j][k]) for k in ("nx", "ny", "nz")] for j in js])
    dt_all = np.array([float(T[j]["d_mm"]) for j in js])
    # truth {0} origin by eq. 11 over exactly the planes msmcal reports (the spec's definition)
    X_lsq = np.linalg.lstsq(nt_all, dt_all, rcond=None)[0] if len(js) >= 3 else X_lsq_true
    for j in js:
        e, t = E[j], T[j]
        ne = np.array([float(e[k]) for k in ("nx", "ny", "nz")])
        nt = np.array([float(t[k]) for k in ("nx", "ny", "nz")])
        en.append(ang(ne, nt))
        ed.append(float(e["d_mm"]) - float(t["d_mm"]))
        ea.append(float(e["alpha_deg"]) - float(t["alpha_deg"]))
        eb.append(float(e["beta_deg"]) - float(t["beta_deg"]))
        et.append(float(e["trans_mm"]) - float(t["trans_mm"]))
        n0 = R_W0.T @ nt
        et_lsq.append(float(e["trans_mm"]) - (float(t["d_mm"]) - nt @ X_lsq))
        for lst, k in ((sa, "sigma_alpha_deg"), (sb, "sigma_beta_deg"), (st, "sigma_trans_mm")):
            if k in e and e[k] not in ("", None):
                lst.append(float(e[k]))
    out["normal_err_deg"] = {"rms": rms(en), "max": max(en) if en else float("nan")}
    out["d_err_mm"] = {"rms": rms(ed), "max_abs": float(np.max(np.abs(ed))) if ed else float("nan")}
    out["alpha_err_deg"] = {"rms": rms(ea), "mean": float(np.mean(ea)) if ea else float("nan"),
                            "sigma_rms": rms(sa)}
    out["beta_err_deg"] = {"rms": rms(eb), "mean": float(np.mean(eb)) if eb else float("nan"),
                           "sigma_rms": rms(sb)}
    out["trans_err_mm_vs_physical_XO"] = {"rms": rms(et), "mean": float(np.mean(et)) if et else float("nan")}
    # the same with every truth plane the session shows (scan + fast_only + neutral)
    extra = read_csv(os.path.join(tru, "fast_only_planes.csv")) + read_csv(os.path.join(tru, "neutral_plane.csv"))
    n_ex = np.array([[float(r[k]) for k in ("nx", "ny", "nz")] for r in extra])
    d_ex = np.array([float(r["d_mm"]) for r in extra])
    X_all = np.linalg.lstsq(np.vstack([nt_all, n_ex]), np.r_[dt_all, d_ex], rcond=None)[0] if len(js) >= 3 else X_lsq
    et_all = [float(E[j]["trans_mm"]) - (dt - n @ X_all) for j, n, dt in zip(js, nt_all, dt_all)]
    out["trans_err_mm_vs_lsq_all_planes"] = {"rms": rms(et_all), "mean": float(np.mean(et_all)) if et_all else float("nan"),
                                             "std": float(np.std(et_all)) if et_all else float("nan")}
    out["trans_err_mm_vs_lsq_origin"] = {"rms": rms(et_lsq), "mean": float(np.mean(et_lsq)) if et_lsq else float("nan"),
                                         "std": float(np.std(et_lsq)) if et_lsq else float("nan"),
                                         "sigma_rms": rms(st)}
    # beams
    TB = {int(r["beam"]): r for r in read_csv(os.path.join(tru, "beams.csv"))}
    pb = os.path.join(res, "beams.csv")
    out["beams"] = {}
    if os.path.isfile(pb):
        for r in read_csv(pb):
            i = int(r["beam"])
            ve = np.array([float(r[k]) for k in ("vx", "vy", "vz")])
            pe = np.array([float(r[k]) for k in ("px", "py", "pz")])
            vt = np.array([float(TB[i][k]) for k in ("vx", "vy", "vz")])
            pt = np.array([float(TB[i][k]) for k in ("px", "py", "pz")])
            vt /= np.linalg.norm(vt)
            ven = ve / np.linalg.norm(ve)
            # distance of the true mirror hit point from the estimated line
            w = pt - pe
            dist = float(np.linalg.norm(w - (w @ ven) * ven))
            out["beams"][i] = {"dir_err_deg": ang(ve, vt), "sign_ok": bool(ve @ vt > 0),
                               "dist_at_mirror_mm": dist}
    # validation
    pv = os.path.join(res, "validation.csv")
    if os.path.isfile(pv):
        V = read_csv(pv)
        if V:
            out["validation"] = {"n": len(V), "rms_px": rms([float(r["err_px"]) for r in V]),
                                 "rms_deg": rms([float(r["err_deg"]) for r in V])}
    # hall
    ph = os.path.join(res, "hall_model.yaml")
    if os.path.isfile(ph):
        hm = yaml.safe_load(open(ph))
        dt_true = float(open(os.path.join(tru, "delta_t.txt")).read())

        def find(o, key):
            if isinstance(o, dict):
                for k, v in o.items():
                    if k == key:
                        return v
                    r = find(v, key)
                    if r is not None:
                        return r
            elif isinstance(o, list):
                for v in o:
                    r = find(v, key)
                    if r is not None:
                        return r
            return None

        dte = find(hm, "delta_t_s")
        out["hall"] = {"delta_t_s": dte, "truth": dt_true,
                       "err_ms": (float(dte) - dt_true) * 1e3 if dte is not None else None}
    ps = os.path.join(res, "summary.json")
    if os.path.isfile(ps):
        try:
            out["summary"] = json.load(open(ps))
        except Exception as ex:  # noqa
            out["summary"] = "unreadable: %s" % ex
    if as_json:
        print(json.dumps(out, indent=1, default=str))
    else:
        print("== %s" % d)
        print("planes: %s; missing j: %s" % (out["planes"], out["missing_triggers"]))
        print("normal error deg: RMS %.4f max %.4f" % (out["normal_err_deg"]["rms"], out["normal_err_deg"]["max"]))
        print("d (W) error mm: RMS %.4f max|.| %.4f" % (out["d_err_mm"]["rms"], out["d_err_mm"]["max_abs"]))
        print("alpha err deg: RMS %.4f (mean %.4f; msmcal sigma RMS %.4f)" % (
            out["alpha_err_deg"]["rms"], out["alpha_err_deg"]["mean"], out["alpha_err_deg"]["sigma_rms"]))
        print("beta  err deg: RMS %.4f (mean %.4f; msmcal sigma RMS %.4f)" % (
            out["beta_err_deg"]["rms"], out["beta_err_deg"]["mean"], out["beta_err_deg"]["sigma_rms"]))
        print("trans err mm vs physical X_O: RMS %.4f (mean %.4f)" % (
            out["trans_err_mm_vs_physical_XO"]["rms"], out["trans_err_mm_vs_physical_XO"]["mean"]))
        print("trans err mm vs eq.11 origin: RMS %.4f (mean %.4f, std %.4f; sigma RMS %.4f)" % (
            out["trans_err_mm_vs_lsq_origin"]["rms"], out["trans_err_mm_vs_lsq_origin"]["mean"],
            out["trans_err_mm_vs_lsq_origin"]["std"], out["trans_err_mm_vs_lsq_origin"]["sigma_rms"]))
        print("trans err mm vs eq.11 origin over scan+fast_only+neutral planes: RMS %.4f (mean %.4f, std %.4f)" % (
            out["trans_err_mm_vs_lsq_all_planes"]["rms"], out["trans_err_mm_vs_lsq_all_planes"]["mean"],
            out["trans_err_mm_vs_lsq_all_planes"]["std"]))
        for i, b in sorted(out["beams"].items()):
            print("beam %d: direction err %.4f deg (sign %s), line-to-true-hit distance %.3f mm" % (
                i, b["dir_err_deg"], "ok" if b["sign_ok"] else "FLIPPED", b["dist_at_mirror_mm"]))
        if "validation" in out:
            print("validation (msmcal): n %d RMS %.3f px %.4f deg" % (
                out["validation"]["n"], out["validation"]["rms_px"], out["validation"]["rms_deg"]))
        if "hall" in out:
            h = out["hall"]
            print("hall delta_t: %s s (truth %s) err %s ms" % (h["delta_t_s"], h["truth"],
                                                              "%.4f" % h["err_ms"] if h["err_ms"] is not None else "n/a"))
    return out


if __name__ == "__main__":
    main(sys.argv[1], "--json" in sys.argv)
