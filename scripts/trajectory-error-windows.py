#!/usr/bin/env python3
"""Position error of a planar trajectory against its truth, per time window (evaluation only).
Both files are TUM (stamp x y z qx qy qz qw); each estimated pose takes the truth interpolated at
its stamp (truth samples at most 0.05 s apart), the estimate is SE(2)-aligned to the truth (least
squares over all poses; --no-align: as given), and the RMS position error is printed overall and
per window of --window seconds from the first pose.
Usage: scripts/trajectory-error-windows.py EST.tum GT.tum [--window 60] [--no-align]
Pure Python 3, no packages."""
import argparse
import bisect
import math


def load(path):
    out = []
    with open(path) as f:
        for line in f:
            if line.startswith('#') or not line.strip():
                continue
            v = line.split()
            out.append((float(v[0]), float(v[1]), float(v[2])))
    return out


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument('est')
    parser.add_argument('gt')
    parser.add_argument('--window', type=float, default=60.0)
    parser.add_argument('--no-align', action='store_true')
    args = parser.parse_args()
    est, gt = load(args.est), load(args.gt)
    stamps = [g[0] for g in gt]
    pairs = []
    for t, x, y in est:
        i = bisect.bisect_left(stamps, t)
        if i == 0 or i >= len(gt) or gt[i][0] - gt[i - 1][0] > 0.05:
            continue
        a, b = gt[i - 1], gt[i]
        u = (t - a[0]) / (b[0] - a[0])
        pairs.append((t, x, y, a[1] + u * (b[1] - a[1]), a[2] + u * (b[2] - a[2])))
    if not pairs:
        raise SystemExit('no estimated pose within the truth')
    n = len(pairs)
    c, s, tx, ty = 1.0, 0.0, 0.0, 0.0
    if not args.no_align:
        mx = sum(p[1] for p in pairs) / n
        my = sum(p[2] for p in pairs) / n
        gx = sum(p[3] for p in pairs) / n
        gy = sum(p[4] for p in pairs) / n
        sxx = sum((p[1] - mx) * (p[3] - gx) + (p[2] - my) * (p[4] - gy) for p in pairs)
        sxy = sum((p[1] - mx) * (p[4] - gy) - (p[2] - my) * (p[3] - gx) for p in pairs)
        theta = math.atan2(sxy, sxx)
        c, s = math.cos(theta), math.sin(theta)
        tx, ty = gx - (c * mx - s * my), gy - (s * mx + c * my)
    t0 = pairs[0][0]
    windows = {}
    total = 0.0
    for t, x, y, gx, gy in pairs:
        e2 = (c * x - s * y + tx - gx) ** 2 + (s * x + c * y + ty - gy) ** 2
        total += e2
        windows.setdefault(int((t - t0) // args.window), []).append(e2)
    print('RMS %.4f m over %d poses' % (math.sqrt(total / n), n))
    for k in sorted(windows):
        v = windows[k]
        print('t = %6.0f .. %6.0f s: %.3f m (%d poses)' %
              (k * args.window, (k + 1) * args.window, math.sqrt(sum(v) / len(v)), len(v)))


if __name__ == '__main__':
    main()
