#!/usr/bin/env python3
"""The mecanum robot's travel per wheel turn, forward, sideways and turning, per run.

For every omni4 run of the OptiOdom sessions (docs/calibrate.md, "The mecanum robot
across kinds of motion"): the body-frame steps of motion capture over 20 rows are
regressed on the nominal kinematics' steps of the wheels (forward (w1-w2+w3-w4)/4 r,
sideways -(w1+w2-w3-w4)/4 r, turn -(w1+w2+w3+w4)/4 r/0.21), one scale each; a run goes
forward or sideways, whichever the wheels say it did more. Printed per session and
direction: the run count, the cycle stretch (index.csv), each scale with its spread
over the runs, and each over the stretch.

    python3 scripts/omni4_direction_scales.py [SESSIONS_DIR]   (default ../shared/real/sessions)
"""
import collections
import csv
import glob
import os
import sys

import numpy as np

S = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
    os.path.dirname(__file__), "..", "..", "shared", "real", "sessions")
R, L, COUNTS = 0.03, 0.21, 11520
idx = {r["folder"]: r for r in csv.DictReader(open(os.path.join(S, "index.csv")))}
agg = collections.defaultdict(list)
for f in sorted(glob.glob(os.path.join(S, "omni4-*"))):
    name = os.path.basename(f)
    r = np.genfromtxt(os.path.join(f, "recording.csv"), delimiter=",", names=True)
    th = np.unwrap(r["theta"])
    w = np.stack([r["enc_w%d" % i] for i in range(1, 5)], 1) * 2 * np.pi / COUNTS
    i0 = np.arange(0, len(th) - 20, 20)
    i1 = i0 + 20
    dx, dy, dth = r["x"][i1] - r["x"][i0], r["y"][i1] - r["y"][i0], th[i1] - th[i0]
    mid = th[i0] + dth / 2
    bx = np.cos(mid) * dx + np.sin(mid) * dy
    by = -np.sin(mid) * dx + np.cos(mid) * dy
    dw = w[i1] - w[i0]
    fwd = (dw[:, 0] - dw[:, 1] + dw[:, 2] - dw[:, 3]) / 4 * R
    side = -(dw[:, 0] + dw[:, 1] - dw[:, 2] - dw[:, 3]) / 4 * R
    turn = -dw.sum(1) / 4 * R / L
    sideways = np.std(side) > np.std(fwd)
    step, body = (side, by) if sideways else (fwd, bx)
    k_t = np.dot(step, body) / np.dot(step, step)
    k_w = np.dot(turn, dth) / np.dot(turn, turn)
    st = float(idx[name]["stretch_real_over_nominal"])
    agg[(("sideways" if sideways else "forward"), name[6:-7])].append((st, k_t, k_w))
print("| direction | session | runs | stretch | travel | turn | travel / stretch | turn / stretch |")
print("|---|---|---|---|---|---|---|---|")
for (d, sess), v in sorted(agg.items()):
    v = np.array(v)
    m, s = v.mean(0), v.std(0)
    print("| %s | %s | %d | %.4f | %.4f ± %.4f | %.4f ± %.4f | %.4f | %.4f |" % (
        d, sess, len(v), m[0], m[1], s[1], m[2], s[2],
        np.mean(v[:, 1] / v[:, 0]), np.mean(v[:, 2] / v[:, 0])))
