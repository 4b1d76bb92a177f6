#!/usr/bin/env python3
"""How well a map's landmark covariance describes its error against a ground-truth map.

Usage: scripts/map-covariance-check.py MAP.json GT_MARKERS.json

For the point landmarks of MAP.json that GT_MARKERS.json also holds (matched by family and id),
e = p_map - p_true (x, y; no alignment: the map's covariance is in the gauge of its start priors,
which is the truth's frame when the datasets were imported with --known-start). Prints, per
coordinate (1 = the covariance describes the error; above 1 = the map is more wrong than it
claims):
  marginal:  sum_l e_l^T Sigma_l^-1 e_l / (2 N)       (position_covariance, each landmark alone)
  joint:     e^T (F F^T + blockdiag(D_l))^-1 e / (2 N)  (with position_covariance_factor)
and the RMS error beside the RMS of the claimed sigmas. Pure Python (no numpy), evaluation only.
"""
import json
import math
import sys


def load_points(path):
    with open(path) as f:
        data = json.load(f)
    points = {}
    for m in data["markers"]:
        if "p_world_marker" in m:
            points[(m["family"], m["id"])] = m
    return points


def solve(a, b):
    """Solves a x = b (a symmetric positive definite, lists), by Gaussian elimination."""
    n = len(a)
    m = [row[:] + [b[i]] for i, row in enumerate(a)]
    for c in range(n):
        p = max(range(c, n), key=lambda r: abs(m[r][c]))
        m[c], m[p] = m[p], m[c]
        for r in range(c + 1, n):
            f = m[r][c] / m[c][c]
            for k in range(c, n + 1):
                m[r][k] -= f * m[c][k]
    x = [0.0] * n
    for r in range(n - 1, -1, -1):
        x[r] = (m[r][n] - sum(m[r][k] * x[k] for k in range(r + 1, n))) / m[r][r]
    return x


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__.strip().splitlines()[2])
    est, truth = load_points(sys.argv[1]), load_points(sys.argv[2])
    keys = sorted(k for k in est if k in truth and "position_covariance" in est[k])
    if not keys:
        sys.exit("no landmark of the map with a position_covariance is in the ground truth")
    errors, marginal, claimed = [], 0.0, 0.0
    for k in keys:
        e = [est[k]["p_world_marker"][i] - truth[k]["p_world_marker"][i] for i in range(2)]
        c = est[k]["position_covariance"]
        s = [[c[0], c[1]], [c[3], c[4]]]
        marginal += sum(e[i] * solve(s, e)[i] for i in range(2))
        claimed += s[0][0] + s[1][1]
        errors += e
    n = len(keys)
    rms = math.sqrt(sum(v * v for v in errors) / n)
    print(f"{n} landmarks: RMS position error {rms:.4f} m, RMS of the claimed sigmas {math.sqrt(claimed / n):.4f} m")
    print(f"normalized error per coordinate, marginals: {marginal / (2 * n):.2f}")
    if all("position_covariance_factor" in est[k] for k in keys):
        rows = []
        for k in keys:
            f = est[k]["position_covariance_factor"]
            kk = len(f) // 3
            rows += [f[0:kk], f[kk:2 * kk]]
        sigma = [[sum(a * b for a, b in zip(rows[i], rows[j])) for j in range(2 * n)] for i in range(2 * n)]
        for i, k in enumerate(keys):
            c = est[k]["position_covariance"]
            for r in range(2):
                for q in range(2):
                    # Within a landmark's block the factor's part is replaced by the marginal
                    # (F F^T + D = Sigma_l there).
                    sigma[2 * i + r][2 * i + q] = c[3 * r + q]
        joint = sum(a * b for a, b in zip(errors, solve(sigma, errors)))
        print(f"normalized error per coordinate, joint (factor of rank {len(rows[0])}): {joint / (2 * n):.2f}")


if __name__ == "__main__":
    main()
