#!/usr/bin/env python3
"""The sensor errors of an MRCLAM run measured against its Vicon truth (evaluation only: nothing
here feeds the estimator). For each robot:
  - the motion-capture heading against the direction of travel (median of atan2(dy, dx) - theta
    over 0.1 s steps at >= 0.05 m/s turning < 0.15 rad/s): the yaw of the Vicon frame on the robot;
  - the bearing error e = measured - true (from the Vicon pose and landmark) fitted as
    e = a + kappa * bearing + c * sin(bearing) / range (least squares over |e| < 0.05 rad):
    a constant offset, a bearing scale error (a focal length error) and a sensor ahead of the
    tracked centre by c metres;
  - the robust spread (1.4826 MAD) of e, and the range error fitted as (k range + b);
then the median relative range error (measured - true) / true per landmark over all robots and
per robot-landmark pair (pairs with at least 10 sightings), and per robot in bins of |true bearing|
(a camera that ranges a code by its apparent size reads its depth, range cos(bearing)).
The robots' tables are printed first, the per-bearing table last.
Usage: scripts/mrclam-sensor-truth.py [RUN_DIR]   (default ../shared/data/mrclam/MRCLAM_Dataset6)
Pure Python 3, no packages."""
import bisect
import math
import os
import sys


def rows(path):
    out = []
    with open(path) as f:
        for line in f:
            if line.startswith('#') or not line.strip():
                continue
            out.append([float(x) for x in line.split()])
    return out


def wrap(a):
    return math.atan2(math.sin(a), math.cos(a))


def median(v):
    v = sorted(v)
    return v[len(v) // 2]


def mad(v):
    m = median(v)
    return 1.4826 * median([abs(x - m) for x in v])


def solve(A, b):
    n = len(b)
    M = [A[i][:] + [b[i]] for i in range(n)]
    for i in range(n):
        p = max(range(i, n), key=lambda r: abs(M[r][i]))
        M[i], M[p] = M[p], M[i]
        for r in range(n):
            if r != i:
                f = M[r][i] / M[i][i]
                for c in range(i, n + 1):
                    M[r][c] -= f * M[i][c]
    return [M[i][n] / M[i][i] for i in range(n)]


def main():
    default = os.path.join(os.path.dirname(__file__), '..', '..', 'shared', 'data', 'mrclam', 'MRCLAM_Dataset6')
    run = sys.argv[1] if len(sys.argv) > 1 else default
    subject_of = {int(r[1]): int(r[0]) for r in rows(os.path.join(run, 'Barcodes.dat'))}
    landmarks = {int(r[0]): (r[1], r[2]) for r in rows(os.path.join(run, 'Landmark_Groundtruth.dat'))}
    print('robot  vicon_yaw_rad  bearing: a_rad  kappa  c_m  spread_rad  n | range: k  b_m')
    relative = {}  # (landmark, robot) -> relative range errors
    bearing_rows = []
    robot = 1
    while os.path.exists(os.path.join(run, 'Robot%d_Groundtruth.dat' % robot)):
        gt = rows(os.path.join(run, 'Robot%d_Groundtruth.dat' % robot))
        stamps = [g[0] for g in gt]
        # Vicon heading against the direction of travel.
        yaw = []
        for i in range(0, len(gt) - 10, 5):
            a, b = gt[i], gt[i + 10]
            dt = b[0] - a[0]
            turn = wrap(b[3] - a[3])
            if dt <= 0 or math.hypot(b[1] - a[1], b[2] - a[2]) / dt < 0.05 or abs(turn) / dt > 0.15:
                continue
            e = wrap(math.atan2(b[2] - a[2], b[1] - a[1]) - (a[3] + 0.5 * turn))
            if abs(e) < 0.5:
                yaw.append(e)
        A = [[0.0] * 3 for _ in range(3)]
        rhs = [0.0] * 3
        errors = []
        R = [[0.0] * 2 for _ in range(2)]
        rr = [0.0] * 2
        by_bearing = {}
        for t, code, rng, bearing in rows(os.path.join(run, 'Robot%d_Measurement.dat' % robot)):
            subject = subject_of.get(int(code))
            if subject not in landmarks:
                continue
            i = bisect.bisect_left(stamps, t)
            if i == 0 or i >= len(gt) or gt[i][0] - gt[i - 1][0] > 0.05:
                continue
            a, b = gt[i - 1], gt[i]
            u = (t - a[0]) / (b[0] - a[0])
            x, y = a[1] + u * (b[1] - a[1]), a[2] + u * (b[2] - a[2])
            theta = a[3] + u * wrap(b[3] - a[3])
            lx, ly = landmarks[subject]
            true_range = math.hypot(lx - x, ly - y)
            true_bearing = wrap(math.atan2(ly - y, lx - x) - theta)
            e = wrap(bearing - true_bearing)
            if abs(e) < 0.05:
                f = [1.0, true_bearing, math.sin(true_bearing) / true_range]
                for p in range(3):
                    rhs[p] += f[p] * e
                    for q in range(3):
                        A[p][q] += f[p] * f[q]
                errors.append(e)
                er = rng - true_range
                if abs(er) < 1.0:
                    relative.setdefault((subject, robot), []).append(er / true_range)
                    edge = min(int(abs(true_bearing) / 0.1), 5)  # 0.5-0.7 rad share the last bin
                    by_bearing.setdefault(edge, []).append(er / true_range)
                    g = [true_range, 1.0]
                    for p in range(2):
                        rr[p] += g[p] * er
                        for q in range(2):
                            R[p][q] += g[p] * g[q]
        offset, kappa, ahead = solve(A, rhs)
        k, b = solve(R, rr)
        print('robot%d  %+.4f  %+.4f  %+.4f  %+.3f  %.4f  %d | %+.3f  %+.3f' %
              (robot, median(yaw), offset, kappa, ahead, mad(errors), len(errors), k, b))
        bearing_rows.append('robot%d ' % robot + ' '.join(
            '%+5.1f%%' % (100 * median(by_bearing[e])) if e in by_bearing else '    - ' for e in range(6)))
        robot += 1
    per_landmark = {}
    for (subject, _), v in relative.items():
        per_landmark.setdefault(subject, []).extend(v)
    pairs = [median(v) for v in relative.values() if len(v) >= 10]
    landmark_medians = [median(v) for v in per_landmark.values()]
    print('median relative range error per landmark (all robots): %+.3f .. %+.3f; per robot-landmark '
          'pair: %+.3f .. %+.3f (%d pairs)' % (min(landmark_medians), max(landmark_medians), min(pairs),
                                               max(pairs), len(pairs)))
    print('median relative range error per |bearing| bin (rad): 0-0.1 0.1-0.2 0.2-0.3 0.3-0.4 0.4-0.5 0.5-')
    for line in bearing_rows:
        print(line)


if __name__ == '__main__':
    main()
