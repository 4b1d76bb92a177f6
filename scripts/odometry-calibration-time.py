#!/usr/bin/env python3
"""The correlation time of a planar robot's odometry turn scale, from mapped robots' data (no
ground truth): for each DATASET with its smoothed trajectory SMOOTHED_DIR/<name>.tum (written by
`waymark map build --trajectory-dir`), the turn of the smoothed trajectory g and of the odometry c
(odometry.tum, its stamps moved by the map's odometry_delay_s of that dataset) over STEP-second
steps (default 1 s); the residual e = g - (1 + k) c after the dataset's own constant scale k
(least squares); the autocovariance of the turn scale's variation at lag L steps,
    R(L) = sum_i e_i e_{i+L} c_i c_{i+L} / sum_i (c_i c_{i+L})^2,
pooled over the datasets (lag 0 is left out: it holds the white odometry noise); a first-order
Gauss-Markov process has R(L) = sigma^2 exp(-L step / tau). Printed: R(L) for L = 1 .. the first
lag with R <= 0 (at most MAX_LAG s, default 60), and tau and sigma from the least-squares line
through log R(L) weighted by R(L) (the correlation time the EKF's --calibration-time takes).
The last line is 'sigma,tau' alone (for scripts: waymark localize --turn-fluctuation sigma,tau, or
--calibration-time tau). Usage:
  scripts/odometry-calibration-time.py MAP.json SMOOTHED_DIR DATASET... [--step S] [--max-lag S]
Pure Python 3, no packages."""
import bisect
import json
import math
import os
import sys


def read_tum(path):
    out = []
    with open(path) as f:
        for line in f:
            if line.startswith('#') or not line.strip():
                continue
            v = [float(x) for x in line.split()]
            out.append((v[0], 2.0 * math.atan2(v[6], v[7])))
    # unwrap
    un = [out[0]]
    for t, th in out[1:]:
        un.append((t, un[-1][1] + math.atan2(math.sin(th - un[-1][1]), math.cos(th - un[-1][1]))))
    return un


def at(series, stamps, t):
    j = bisect.bisect_left(stamps, t)
    if j <= 0 or j >= len(series):
        return None
    (ta, a), (tb, b) = series[j - 1], series[j]
    return a + (t - ta) / (tb - ta) * (b - a)


def main():
    args = sys.argv[1:]
    step, max_lag = 1.0, 60.0
    rest = []
    i = 0
    while i < len(args):
        if args[i] == '--step':
            step = float(args[i + 1])
            i += 2
        elif args[i] == '--max-lag':
            max_lag = float(args[i + 1])
            i += 2
        else:
            rest.append(args[i])
            i += 1
    if len(rest) < 3:
        sys.exit(__doc__)
    model = json.load(open(rest[0]))
    delays = {d['name']: d['noise'].get('odometry_delay_s', 0.0)
              for d in model.get('range_bearing_sensor', {}).get('datasets', [])}
    smoothed_dir = rest[1]
    n_lags = int(max_lag / step)
    num = [0.0] * (n_lags + 1)
    den = [0.0] * (n_lags + 1)
    for data in rest[2:]:
        name = os.path.basename(os.path.normpath(data))
        ref = read_tum(os.path.join(smoothed_dir, name + '.tum'))
        odo = read_tum(os.path.join(data, 'odometry.tum'))
        delay = delays.get(name, 0.0)
        odo = [(t + delay, th) for t, th in odo]
        ref_t, odo_t = [x[0] for x in ref], [x[0] for x in odo]
        steps = {}
        t, n = max(ref_t[0], odo_t[0]), 0
        while t + step < min(ref_t[-1], odo_t[-1]):
            g0, g1, c0, c1 = at(ref, ref_t, t), at(ref, ref_t, t + step), at(odo, odo_t, t), at(odo, odo_t, t + step)
            if None not in (g0, g1, c0, c1):
                steps[n] = (g1 - g0, c1 - c0)
            t += step
            n += 1
        k = sum(g * c for g, c in steps.values()) / sum(c * c for g, c in steps.values())
        e = {i: (g - k * c, c) for i, (g, c) in steps.items()}
        for lag in range(1, n_lags + 1):
            for i, (ei, ci) in e.items():
                if i + lag in e:
                    ej, cj = e[i + lag]
                    num[lag] += ei * ej * ci * cj
                    den[lag] += (ci * cj) ** 2
        print('%s: constant turn scale %+.4f (smoothed turn / odometry turn - 1), %d steps' % (name, k - 1.0, len(e)))
    R = []
    for lag in range(1, n_lags + 1):
        r = num[lag] / den[lag] if den[lag] > 0 else 0.0
        if r <= 0.0:
            break
        R.append((lag * step, r))
    print('R(lag):', ' '.join('%g:%.5f' % (l, r) for l, r in R))
    if len(R) < 2:
        print('too few positive lags for a fit: no fluctuation (sigma 0)')
        print('0,%.3f' % step)
        return
    sw = sum(r for l, r in R)
    ml = sum(r * l for l, r in R) / sw
    my = sum(r * math.log(r) for l, r in R) / sw
    slope = sum(r * (l - ml) * (math.log(r) - my) for l, r in R) / sum(r * (l - ml) ** 2 for l, r in R)
    tau = -1.0 / slope if slope < 0 else float('inf')
    sigma = math.sqrt(math.exp(my - slope * ml))
    print('Gauss-Markov fit: tau %.2f s, sigma %.4f' % (tau, sigma))
    print('%.4f,%.3f' % (sigma, tau))


main()
