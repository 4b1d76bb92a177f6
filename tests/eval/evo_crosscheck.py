#!/usr/bin/env python3
"""Cross-check of `waymark eval` against evo's own code (not part of ctest).

Writes random trajectory pairs (gaps, stamp offsets, unequal lengths, noise, a rigid or
similarity transform between the frames) as TUM files, runs `waymark eval --json` and evo's
sync.associate_trajectories + PosePath3D.align + metrics.APE / metrics.RPE on the same files,
and compares every statistic. Needs numpy, scipy and evo's sources: an installed `evo`
package, or EVO_SRC=<path to a checkout of github.com/MichaelGrupp/evo> (its evo/core is
enough; evo.tools is not imported).

  python3 tests/eval/evo_crosscheck.py build-NAME/waymark [cases]
Exit status 0 when every figure agrees within 1e-9 (relative), 1 otherwise.
"""
import json
import math
import os
import subprocess
import sys
import tempfile

if os.environ.get("EVO_SRC"):
    sys.path.insert(0, os.environ["EVO_SRC"])
import numpy as np  # noqa: E402
from evo.core import metrics, sync  # noqa: E402
from evo.core.trajectory import PoseTrajectory3D  # noqa: E402
from evo.core.units import Unit  # noqa: E402


def quat_from_rotvec(v):
    angle = np.linalg.norm(v)
    if angle < 1e-15:
        return np.array([0.0, 0.0, 0.0, 1.0])
    axis = v / angle
    return np.concatenate([axis * math.sin(angle / 2), [math.cos(angle / 2)]])


def quat_mul(a, b):  # xyzw
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz])


def rotate(q, p):
    return quat_mul(quat_mul(q, np.concatenate([p, [0.0]])), q * np.array([-1, -1, -1, 1]))[:3]


def write_tum(path, stamps, positions, quats):
    with open(path, "w") as f:
        for t, p, q in zip(stamps, positions, quats):
            f.write("%.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n" % (t, *p, *q))


def make_case(rng, path_gt, path_est):
    n = int(rng.integers(30, 300))
    stamps = np.cumsum(rng.uniform(0.02, 0.1, n))
    positions = np.cumsum(rng.normal(0, 0.2, (n, 3)), axis=0)
    quats = [quat_from_rotvec(rng.normal(0, 1.0, 3)) for _ in range(n)]
    write_tum(path_gt, stamps, positions, quats)
    keep = rng.uniform(size=n) > 0.2  # gaps
    q0 = quat_from_rotvec(rng.normal(0, 1.0, 3))
    t0, s0 = rng.normal(0, 5, 3), rng.uniform(0.5, 2.0)
    est_stamps = stamps[keep] + rng.uniform(-0.012, 0.012, keep.sum())  # some beyond 0.01 s
    est_pos = [s0 * rotate(q0, p + rng.normal(0, 0.05, 3)) + t0 for p in positions[keep]]
    est_q = [quat_mul(q0, quat_mul(q, quat_from_rotvec(rng.normal(0, 0.02, 3)))) for q, k in zip(quats, keep) if k]
    order = np.argsort(est_stamps, kind="stable")
    write_tum(path_est, est_stamps[order], np.array(est_pos)[order], np.array(est_q)[order])


def load(path):
    d = np.loadtxt(path, comments="#")
    return PoseTrajectory3D(positions_xyz=d[:, 1:4], orientations_quat_wxyz=d[:, [7, 4, 5, 6]], timestamps=d[:, 0])


def evo_figures(gt, est, align, scale, rpe):
    out = {}
    relations = [("ape_t", metrics.PoseRelation.translation_part), ("ape_r", metrics.PoseRelation.rotation_angle_deg)]
    for key, relation in relations + [("rpe_t", relations[0][1]), ("rpe_r", relations[1][1])]:
        ref, e = sync.associate_trajectories(load(gt), load(est), 0.01)
        if align or scale:
            e.align(ref, correct_scale=scale, correct_only_scale=scale and not align)
        if key.startswith("ape"):
            metric = metrics.APE(relation)
        else:
            delta, unit = rpe
            metric = metrics.RPE(relation, delta, Unit.meters if unit == "m" else Unit.frames, 0.1, False)
        metric.process_data((ref, e))
        out[key] = metric.get_all_statistics()
        out[key]["count"] = len(metric.error)
    return out


def waymark_figures(binary, gt, est, align, scale, rpe, json_path):
    args = [binary, "eval", "--est", est, "--gt", gt, "--align", "se3" if align else "none",
            "--rpe-delta", str(rpe[0]), "--rpe-unit", rpe[1], "--json", json_path]
    if scale:
        args.append("--scale")
    subprocess.run(args, check=True, stdout=subprocess.DEVNULL)
    j = json.load(open(json_path))
    ape_t = dict(j["ate"], count=j["ate"]["pairs"])
    return {"ape_t": ape_t, "ape_r": j["ate"]["rotation_deg"], "rpe_t": j["rpe"]["translation_m"],
            "rpe_r": j["rpe"]["rotation_deg"]}


def main():
    binary = sys.argv[1]
    cases = int(sys.argv[2]) if len(sys.argv) > 2 else 20
    rng = np.random.default_rng(2024)
    worst, failures = 0.0, 0
    with tempfile.TemporaryDirectory() as tmp:
        gt, est, out = os.path.join(tmp, "gt.tum"), os.path.join(tmp, "est.tum"), os.path.join(tmp, "o.json")
        for case in range(cases):
            make_case(rng, gt, est)
            align, scale = [(True, False), (True, True), (False, False), (False, True)][case % 4]
            rpe = (int(rng.integers(1, 5)), "frames") if case % 2 == 0 else (float(rng.uniform(0.3, 1.5)), "m")
            ours = waymark_figures(binary, gt, est, align, scale, rpe, out)
            theirs = evo_figures(gt, est, align, scale, rpe)
            for key in theirs:
                for stat in ("rmse", "mean", "median", "std", "min", "max", "sse", "count"):
                    a, b = float(ours[key][stat]), float(theirs[key][stat])
                    rel = abs(a - b) / max(abs(b), 1e-12)
                    worst = max(worst, rel) if stat != "count" else worst
                    if rel > 1e-9:
                        failures += 1
                        print("case %d %s %s: waymark %.17g evo %.17g" % (case, key, stat, a, b))
    print("%d cases, %d disagreements, worst relative difference %.3g" % (cases, failures, worst))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
