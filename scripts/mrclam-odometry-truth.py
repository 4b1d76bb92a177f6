#!/usr/bin/env python3
"""The odometry (commanded velocities) of an MRCLAM run against its Vicon truth, per robot
(evaluation only: nothing here feeds the estimator). The command is shifted by DELAY seconds
(the map build's odometry delay; default 0.18 s) and integrated over STEP-second steps (default 1 s);
for every step: commanded turn c and distance u, true turn g and distance s (truth interpolated).
Printed per robot:
  - the turn scale over the whole run, sum(g c) / sum(c^2) - 1, split into turning in place
    (|u| < 0.02 m per step) and turning while driving; the distance scale likewise;
  - the turn scale fitted per WINDOW-second window (default 30 s; windows turning >= 1 rad): its
    mean, spread (std over windows) and the lag-one correlation of consecutive windows, i.e. how
    far and how slowly the 'constant' calibration drifts;
  - the white part: the variance of g - (1 + scale) c per radian turned (q_r's analogue) and of
    the distance error per metre (q_t's analogue) after the robot's own scale.
Usage: scripts/mrclam-odometry-truth.py [RUN_DIR] [--delay S] [--step S] [--window S] [--robot N
--from T0 --to T1]  (the last: the per-step table of robot N for T0..T1 s after its first odometry
stamp). Pure Python 3, no packages."""
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


def main():
    args = sys.argv[1:]
    opts = {'--delay': 0.18, '--step': 1.0, '--window': 30.0, '--robot': 0, '--from': 0.0, '--to': 0.0}
    run = '../shared/data/mrclam/MRCLAM_Dataset6'
    i = 0
    while i < len(args):
        if args[i] in opts:
            opts[args[i]] = float(args[i + 1])
            i += 2
        else:
            run = args[i]
            i += 1
    delay, step, window = opts['--delay'], opts['--step'], opts['--window']
    print('robot | turn scale all / in place / driving | dist scale | window turn scale mean, std, lag-1 corr (n) '
          '| white turn var per rad | white dist var per m')
    for robot in range(1, 6):
        odo = rows(os.path.join(run, 'Robot%d_Odometry.dat' % robot))
        gt = rows(os.path.join(run, 'Robot%d_Groundtruth.dat' % robot))
        gt_t = [r[0] for r in gt]
        # unwrapped true heading
        th = [gt[0][3]]
        for k in range(1, len(gt)):
            th.append(th[-1] + wrap(gt[k][3] - gt[k - 1][3]))

        def truth(t):
            j = bisect.bisect_left(gt_t, t)
            if j <= 0 or j >= len(gt):
                return None
            a, b = gt[j - 1], gt[j]
            if b[0] - a[0] > 0.1:
                return None
            w = (t - a[0]) / (b[0] - a[0])
            return (a[1] + w * (b[1] - a[1]), a[2] + w * (b[2] - a[2]), th[j - 1] + w * (th[j] - th[j - 1]))

        o_t = [r[0] + delay for r in odo]  # the command at stamp t acts at t + delay

        def command(t0, t1):  # integral of v and w over [t0, t1], piecewise constant
            u = c = 0.0
            j = max(0, bisect.bisect_right(o_t, t0) - 1)
            while j < len(odo) and o_t[j] < t1:
                a = max(t0, o_t[j])
                b = min(t1, o_t[j + 1] if j + 1 < len(odo) else t1)
                if b > a:
                    u += odo[j][1] * (b - a)
                    c += odo[j][2] * (b - a)
                j += 1
            return u, c

        t_start = odo[0][0]
        steps = []
        t = max(o_t[0], gt_t[0])
        while t + step < min(o_t[-1], gt_t[-1]):
            p, q = truth(t), truth(t + step)
            if p and q:
                u, c = command(t, t + step)
                s = math.hypot(q[0] - p[0], q[1] - p[1])
                steps.append((t - t_start, u, c, s, q[2] - p[2]))
            t += step

        def scale(sel):
            num = sum(x[4] * x[2] for x in sel)
            den = sum(x[2] * x[2] for x in sel)
            return num / den - 1.0 if den > 0 else float('nan')

        def dscale(sel):
            num = sum(x[3] * abs(x[1]) for x in sel)
            den = sum(x[1] * x[1] for x in sel)
            return num / den - 1.0 if den > 0 else float('nan')

        inplace = [x for x in steps if abs(x[1]) < 0.02]
        driving = [x for x in steps if abs(x[1]) >= 0.02]
        k_all = scale(steps)
        wins = []
        n_per = int(round(window / step))
        for w0 in range(0, len(steps) - n_per + 1, n_per):
            sel = steps[w0:w0 + n_per]
            if sum(abs(x[2]) for x in sel) >= 1.0:
                wins.append(scale(sel))
            else:
                wins.append(None)
        vals = [w for w in wins if w is not None]
        mean = sum(vals) / len(vals)
        std = math.sqrt(sum((w - mean) ** 2 for w in vals) / max(1, len(vals) - 1))
        pairs = [(wins[k] - mean, wins[k + 1] - mean) for k in range(len(wins) - 1)
                 if wins[k] is not None and wins[k + 1] is not None]
        corr = sum(a * b for a, b in pairs) / len(pairs) / (std * std) if pairs else float('nan')
        turned = sum(abs(x[2]) for x in steps)
        white_r = sum((x[4] - (1 + k_all) * x[2]) ** 2 for x in steps) / turned
        d_all = dscale(steps)
        moved = sum(abs(x[1]) for x in steps)
        white_t = sum((x[3] - (1 + d_all) * abs(x[1])) ** 2 for x in steps) / moved
        print('robot%d | %+.3f / %+.3f / %+.3f | %+.3f | %+.3f, %.3f, %+.2f (%d) | %.4f | %.5f' %
              (robot, k_all, scale(inplace), scale(driving), d_all, mean, std, corr, len(vals), white_r, white_t))
        print('  window turn scales:', ' '.join('%+.2f' % w if w is not None else '  . ' for w in wins))
        if int(opts['--robot']) == robot:
            print('  t(s)  cmd dist  cmd turn  true dist  true turn')
            for x in steps:
                if opts['--from'] <= x[0] <= opts['--to']:
                    print('  %6.1f  %+.3f  %.3f  %+.3f  %+.3f' % x)


main()
