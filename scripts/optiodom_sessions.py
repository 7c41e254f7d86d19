#!/usr/bin/env python3
"""Convert a checkout of the OptiOdom dataset into wheelcal's real-sessions folder.

Provenance
----------
Data: the OptiOdom dataset, GitHub ``sousarbarb/optiodom`` at commit
8e025fd7a30c7152132e0ae53ba23bbc909f5a81, by Ricardo B. Sousa, Marcelo R. Petry,
Paulo G. Costa and A. Paulo Moreira: "OptiOdom: a Generic Approach for Odometry
Calibration of Wheeled Mobile Robots", J. Intell. Robot. Syst. 105, 39 (2022),
https://doi.org/10.1007/s10846-022-01630-3.  MIT licence, Copyright (c) 2021 the
authors.  Only data is taken, re-expressed in wheelcal's column layout.

What the conversion does
------------------------
For every run of the differential (``diff``: square, circular, ivanjko), three-wheel
omni (``omni3``: square, circular) and four-wheel mecanum (``omni4``: square, circular)
robots, except the sessions kept apart as held-out data (free-form drives of the
differential robot, omni3 joystick drives, the omni4 circles of December 2020 and the
omni4 square session 080920201205), it writes a folder
``<robot>-<path>-<session>-run-NN`` with

* ``recording.csv``: ``t,enc_<wheel>...,x,y,theta``.  The rows are the authors'
  synchronised file ``<session>_run-NN.csv`` one for one: it is already on the
  odometry cycle (motion capture resampled onto it) and already in the robot's
  start frame (the first row is exactly 0,0,0).  ``t``, ``x``, ``y``, ``theta`` are
  copied as printed (``t`` is the nominal cycle count times the nominal cycle).
  The per-cycle wheel increments become cumulative counts; the first row's
  increments (motion before the start, seen in omni3 runs) are dropped.  The diff
  file lists right then left; ours is left, right.  The omni4 values are wheel
  revolutions per cycle and become integer units of 1/11520 revolution.
* ``robot.toml``: the nominal geometry in the Siegwart convention of
  docs/formats.md (diff: the robot's true published nominal; omni3/omni4: the
  session's metadata file), with a comment header saying where it came from.

and, at the top level, ``index.csv`` (a row per run: direction from the sign of the
true end heading, rows, duration, the nominal geometry's end/max/RMS position error
and end heading error dead-reckoned from the first row (diff: heading at mid-cycle, as
the authors integrate; omni: constant-twist arcs, as wheelcal does), the true end
heading and path length, ``stretch_real_over_nominal`` = motion-capture span over
odometry span from the metadata, the largest heading disagreement in the first second,
the session's controller parameters, our kinematics against the authors' on every
cycle, notes), ``authors_params.json`` (the authors' calibrated parameters per session
from ``data/data.xlsm``, in metres, with the omni ones also in our robot.toml wheel
convention) and ``README.md``.

Session controller parameters (index.csv, robot.toml comment) come from the header of
the on-board log ``<session>.csv``.  The omni4 logs are among the large files the
reference conversion did not have (its text says "log absent; metadata ..."); a full
clone has them, and then that text names the log's parameters instead (falling back to
the metadata when the header has none).  This was not testable here: the mirror used to
check the conversion lacks those files.

Usage
-----
    optiodom_sessions.py --src CHECKOUT --out OUT_DIR     # convert
    optiodom_sessions.py --out OUT_DIR --compare REF_DIR  # compare two converted folders
    (both at once: convert, then compare)

Standard library only.
"""

import argparse
import csv
import json
import math
import os
import re
import sys
import zipfile
import xml.etree.ElementTree as ET

COMMIT = "8e025fd7a30c7152132e0ae53ba23bbc909f5a81"
COMMIT_SHORT = COMMIT[:12]

ROBOTS = {"diff": ["square", "circular", "ivanjko"],
          "omni3": ["square", "circular"],
          "omni4": ["square", "circular"]}


def kept_apart(robot, path, session):
    """Sessions kept out of the converted folder (held-out checks)."""
    if robot == "omni4" and path == "circular" and session.startswith("2312"):
        return True  # the omni4 circles of December 2020
    if robot == "omni4" and path == "square" and session == "080920201205":
        return True  # one omni4 square session
    return False


# The differential robot's true published nominal.
DIFF_D = 0.084
DIFF_B = 0.2
DIFF_GEAR = 43.7
DIFF_ENC = 64
OMNI4_COUNTS_PER_REV = 11520


def die(msg):
    sys.stderr.write("optiodom_sessions: error: %s\n" % msg)
    sys.exit(1)


def g6(v):
    """Six significant digits, as printed by C's %g."""
    return "%g" % v


def read_rows(path):
    with open(path, encoding="utf-8-sig", newline="") as f:
        return [line.rstrip("\r\n").split(",") for line in f if line.strip()]


# --------------------------------------------------------------------------- metadata

def read_metadata(path):
    md = {}
    for row in read_rows(path):
        key = row[0].strip()
        vals = [c.strip() for c in row[1:] if c.strip() != ""]
        md[key] = vals
    return md


def read_session_log(path):
    """The on-board log: header parameters and the runs (list of rows of floats)."""
    if not os.path.isfile(path):
        return None
    rows = read_rows(path)
    params = []
    if len(rows) > 1:
        r = rows[1]
        for k in range(0, len(r) - 1, 2):
            name = r[k].strip().rstrip(":")
            name = re.sub(r"\(m\)$", "", name)
            try:
                value = float(r[k + 1])
            except ValueError:
                continue
            if name:
                params.append((name, value))
    runs = {}
    cur = None
    for r in rows:
        if r[0].strip() == "Run:":
            cur = int(r[1])
            runs[cur] = []
            continue
        if cur is None:
            continue
        try:
            runs[cur].append([float(c) for c in r if c.strip() != ""])
        except ValueError:
            continue
    return {"params": params, "runs": runs}


# --------------------------------------------------------------------------- geometry

def robot_geometry(robot, md):
    """Wheels in the Siegwart convention: list of dicts, plus drive numbers."""
    if robot == "diff":
        r = DIFF_D / 2
        l = DIFF_B / 2
        wheels = [dict(name="left", radius_m=r, alpha_deg=90.0, l_m=l, beta_deg=0.0, gamma_deg=0.0),
                  dict(name="right", radius_m=r, alpha_deg=-90.0, l_m=l, beta_deg=180.0, gamma_deg=0.0)]
        return wheels, DIFF_GEAR, DIFF_GEAR * DIFF_ENC
    if robot == "omni3":
        L = float(md["Li"][0])
        D = [float(x) for x in md["Di"][:3]]
        wheels = omni3_wheels(L, D)
        gear = float(md["ngear"][0])
        return wheels, gear, int(round(gear * float(md["encRes"][0])))
    if robot == "omni4":
        L1, L2 = float(md["Li"][0]), float(md["Li"][1])
        D = [float(x) for x in md["Di"][:4]]
        return omni4_wheels(L1 + L2, D), 1.0, OMNI4_COUNTS_PER_REV
    raise ValueError(robot)


def omni3_wheels(L, D):
    alphas = [-60.0, 60.0, 180.0]
    return [dict(name="w%d" % (i + 1), radius_m=D[i] / 2, l_m=L, alpha_deg=alphas[i],
                 beta_deg=0.0, gamma_deg=0.0) for i in range(3)]


def omni4_wheels(L12, D):
    # Only L1 + L2 enters the authors' model; a square footprint with the same sum.
    l = L12 / 2 / math.sqrt(2)
    spec = [(45.0, 45.0, -45.0), (-45.0, -45.0, 45.0), (135.0, -45.0, 45.0), (-135.0, 45.0, -45.0)]
    return [dict(name="w%d" % (i + 1), radius_m=D[i] / 2, l_m=l, alpha_deg=a, beta_deg=b, gamma_deg=g)
            for i, (a, b, g) in enumerate(spec)]


def toml_float(v):
    s = repr(float(v))
    return s


def robot_toml(robot, path, session, run, direction, md, ctrl_text, ctrl_wrong):
    wheels, gear, cpr = robot_geometry(robot, md)
    dir_txt = " (%s)" % direction if direction else ""
    lines = ["# OptiOdom %s robot, session %s (%s path), run-%s%s," % (robot, session, path, run, dir_txt),
             "# github.com/sousarbarb/optiodom @ %s (MIT), converted" % COMMIT_SHORT,
             "# to the Siegwart convention of formats.md."]
    if robot == "diff":
        lines += ["# Geometry: the robot's true published nominal (84 mm wheels, 0.200 m separation,",
                  "# 43.7:1 gear, 64 counts per motor revolution); counts are raw encoder counts."]
        p = dict(ctrl_text)
        tail = "," if ctrl_wrong else "."
        lines.append("# Session controller parameters (log header): dL0 = %s m, dR0 = %s m, b0 = %s m%s"
                     % (p["dL0"], p["dR0"], p["b0"], tail))
        if ctrl_wrong:
            lines.append("# deliberately WRONG: they drove the on-board odometry and the commanded path, not the counts.")
    else:
        lines.append("# Geometry: the session's own metadata (Li %s, Di %s)."
                     % ("/".join(md["Li"]), "/".join(md["Di"])))
        lines.append("# Session controller parameters: %s." % ctrl_text)
        if robot == "omni4":
            lines += ["# Wheel values were revolutions; counts are units of 1/11520 rev. gamma = +-45 (mecanum)",
                      "# is what reproduces the authors' nominal model; the robot type is not published."]
    lines += ['name = "optiodom-%s"' % robot,
              'kind = "%s"' % ("diff_drive" if robot == "diff" else "omni"),
              "",
              "[drive]",
              'type = "dc"',
              "gear_ratio = %s" % toml_float(gear),
              "encoder_counts_per_rev = %s" % (toml_float(cpr) if robot == "diff" else str(int(cpr)))]
    for w in wheels:
        lines += ["", "[[wheels]]",
                  'name = "%s"' % w["name"],
                  "radius_m = %s" % toml_float(w["radius_m"]),
                  "alpha_deg = %s" % toml_float(w["alpha_deg"]),
                  "l_m = %s" % toml_float(w["l_m"]),
                  "beta_deg = %s" % toml_float(w["beta_deg"]),
                  "gamma_deg = %s" % toml_float(w["gamma_deg"]),
                  "driven = true"]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- kinematics

def fk_authors(robot, md, inc):
    """Body displacement (dx, dy, dth) of one cycle, the authors' nominal model."""
    if robot == "diff":
        k = math.pi * DIFF_D / (DIFF_GEAR * DIFF_ENC)
        dR, dL = k * inc[1], k * inc[0]
        return ((dR + dL) / 2, 0.0, (dR - dL) / DIFF_B)
    if robot == "omni3":
        L = float(md["Li"][0])
        D = [float(x) for x in md["Di"][:3]]
        k = float(md["ngear"][0]) * float(md["encRes"][0])
        w = [math.pi * D[i] * inc[i] / k for i in range(3)]
        s3 = 3 ** 0.5
        return (-s3 / 3 * w[0] + s3 / 3 * w[1],
                -w[0] / 3 - w[1] / 3 + 2 * w[2] / 3,
                -(w[0] + w[1] + w[2]) / (3 * L))
    L12 = float(md["Li"][0]) + float(md["Li"][1])
    D = [float(x) for x in md["Di"][:4]]
    w = [math.pi * D[i] * inc[i] for i in range(4)]  # inc in revolutions
    return ((w[0] - w[1] + w[2] - w[3]) / 4,
            (-w[0] - w[1] + w[2] + w[3]) / 4,
            -(w[0] + w[1] + w[2] + w[3]) / (2 * L12))


def fk_matrix(wheels, cpr):
    """The body displacement (dx, dy, dth) from wheel counts, by our robot.toml model:
    the least-squares solution of the rolling constraints (Siegwart, with the roller
    angle gamma): [sin(a+b+g), -cos(a+b+g), -l cos(b+g)] . xi = r cos(g) phi."""
    A = []
    k = []
    for w in wheels:
        a, b, g = (math.radians(w[key]) for key in ("alpha_deg", "beta_deg", "gamma_deg"))
        A.append([math.sin(a + b + g), -math.cos(a + b + g), -w["l_m"] * math.cos(b + g)])
        k.append(w["radius_m"] * math.cos(g) * 2 * math.pi / cpr)
    cols = []
    for j in range(len(wheels)):
        e = [0.0] * len(wheels)
        e[j] = k[j]
        cols.append(lstsq3(A, e))
    return [[cols[j][i] for j in range(len(wheels))] for i in range(3)]


def fk_apply(M, counts):
    return tuple(sum(m * c for m, c in zip(row, counts)) for row in M)


def lstsq3(A, y):
    n = len(A[0])
    M = [[sum(A[k][i] * A[k][j] for k in range(len(A))) for j in range(n)] for i in range(n)]
    v = [sum(A[k][i] * y[k] for k in range(len(A))) for i in range(n)]
    # Gaussian elimination with partial pivoting on the normal equations.
    aug = [M[i] + [v[i]] for i in range(n)]
    for c in range(n):
        p = max(range(c, n), key=lambda r: abs(aug[r][c]))
        if abs(aug[p][c]) < 1e-300:
            continue
        aug[c], aug[p] = aug[p], aug[c]
        for r in range(n):
            if r != c:
                f = aug[r][c] / aug[c][c]
                aug[r] = [x - f * yv for x, yv in zip(aug[r], aug[c])]
    return [aug[i][n] / aug[i][i] if aug[i][i] else 0.0 for i in range(n)]


def integrate(robot, deltas):
    """Pose from body displacements, from (0,0,0).  The differential robot as the
    authors integrate it (the displacement along the heading at the middle of the
    cycle); the omni robots as wheelcal does (a circular arc at constant twist)."""
    x = y = th = 0.0
    out = [(0.0, 0.0, 0.0)]
    for dx, dy, dth in deltas[1:]:
        if robot == "diff":
            a = th + dth / 2
            c, s = math.cos(a), math.sin(a)
            x += dx * c - dy * s
            y += dx * s + dy * c
        else:
            if abs(dth) < 1e-9:
                ks, kc = 1.0 - dth * dth / 6, dth / 2
            else:
                ks, kc = math.sin(dth) / dth, (1 - math.cos(dth)) / dth
            lx = ks * dx - kc * dy
            ly = kc * dx + ks * dy
            c, s = math.cos(th), math.sin(th)
            x += c * lx - s * ly
            y += s * lx + c * ly
        th += dth
        out.append((x, y, th))
    return out


# --------------------------------------------------------------------------- one run

def convert_run(robot, src_rows, wheels_n):
    """Rows of the authors' synchronised file -> (t, counts, pose strings, increments, notes)."""
    cum = [0] * wheels_n
    out = []
    incs = []
    notes = []
    for i, r in enumerate(src_rows):
        raw = [float(c) for c in r[4:4 + wheels_n]]
        if robot == "diff":
            raw = [raw[1], raw[0]]  # file: right, left
        if robot == "omni4":
            inc = [int(round(v * OMNI4_COUNTS_PER_REV)) for v in raw]
        else:
            inc = [int(round(v)) for v in raw]
        if i == 0:
            if any(inc):
                notes.append("row 0 carried increments [%s] (motion before the start), dropped"
                             % ", ".join(str(v) for v in inc))
            inc = [0] * wheels_n
            raw = [0.0] * wheels_n
        cum = [c + v for c, v in zip(cum, inc)]
        out.append((r[0], list(cum), r[1:4]))
        incs.append((inc, raw))
    return out, incs, notes




def run_stats(robot, md, rows, incs, wheels, cpr):
    n = len(rows)
    t = [float(r[0]) for r in rows]
    gt = [tuple(float(v) for v in r[2]) for r in rows]
    M = fk_matrix(wheels, cpr)
    deltas = [fk_apply(M, inc) for inc, raw in incs]
    odo = integrate(robot, deltas)
    errs = [math.hypot(o[0] - g[0], o[1] - g[1]) for o, g in zip(odo, gt)]
    path = sum(math.hypot(gt[i][0] - gt[i - 1][0], gt[i][1] - gt[i - 1][1]) for i in range(1, n))
    # Heading disagreement at the start: the first second.
    start = 0.0
    for i in range(n):
        if t[i] - t[0] > 1.0:
            break
        start = max(start, abs(odo[i][2] - gt[i][2]))
    # Our kinematics on the written counts against the authors' model on the printed values.
    fk = 0.0
    fk_grid = 0.0
    off_grid = 0.0
    for (inc, raw), d in zip(incs, deltas):
        fk = max(fk, max(abs(a - b) for a, b in zip(fk_authors(robot, md, raw), d)))
        if robot == "omni4":
            on = fk_authors(robot, md, [c / OMNI4_COUNTS_PER_REV for c in inc])
            fk_grid = max(fk_grid, max(abs(a - b) for a, b in zip(on, d)))
            off_grid = max(off_grid, max(abs(v * OMNI4_COUNTS_PER_REV - c) for v, c in zip(raw, inc)))
    return dict(rows=n, duration=t[-1] - t[0], end_err=errs[-1], max_err=max(errs),
                rms=math.sqrt(sum(e * e for e in errs) / n), end_head=gt[-1][2] - odo[-1][2],
                gt_end_head=gt[-1][2], gt_path=path, start=start, fk=fk, fk_grid=fk_grid,
                off_grid=off_grid)


def log_replay_error(robot, log_run, params):
    """Max |on-board pose - replay of the logged counts with params| over x, y, theta."""
    dL, dR, b = params
    k = math.pi / (DIFF_GEAR * DIFF_ENC)
    x = y = th = 0.0
    worst = 0.0
    for i, r in enumerate(log_run):
        if i > 0:
            sL, sR = k * dL * r[1], k * dR * r[2]
            d, dth = (sL + sR) / 2, (sR - sL) / b
            x += d * math.cos(th + dth / 2)
            y += d * math.sin(th + dth / 2)
            th += dth
        worst = max(worst, abs(x - r[3]), abs(y - r[4]), abs(th - r[5]))
    return worst


# --------------------------------------------------------------------------- authors' parameters

NS = {"m": "http://schemas.openxmlformats.org/spreadsheetml/2006/main",
      "r": "http://schemas.openxmlformats.org/officeDocument/2006/relationships"}


def read_xlsx(path):
    z = zipfile.ZipFile(path)
    strings = []
    if "xl/sharedStrings.xml" in z.namelist():
        for si in ET.fromstring(z.read("xl/sharedStrings.xml")).findall("m:si", NS):
            strings.append("".join(t.text or "" for t in si.iter("{%s}t" % NS["m"])))
    wb = ET.fromstring(z.read("xl/workbook.xml"))
    rels = ET.fromstring(z.read("xl/_rels/workbook.xml.rels"))
    rmap = {r.get("Id"): r.get("Target") for r in rels}
    sheets = {}
    for s in wb.find("m:sheets", NS):
        target = rmap[s.get("{%s}id" % NS["r"])].lstrip("/")
        if not target.startswith("xl/"):
            target = "xl/" + target
        rows = {}
        for c in ET.fromstring(z.read(target)).iter("{%s}c" % NS["m"]):
            m = re.match(r"([A-Z]+)(\d+)$", c.get("r"))
            t = c.get("t")
            v = c.find("m:v", NS)
            if t == "inlineStr":
                val = "".join(x.text or "" for x in c.iter("{%s}t" % NS["m"]))
            elif v is None:
                continue
            elif t == "s":
                val = strings[int(v.text)]
            elif t in ("str", "e", "b"):
                val = v.text
            else:
                val = float(v.text)
            rows.setdefault(int(m.group(2)), {})[m.group(1)] = val
        sheets[s.get("name")] = rows
    return sheets


def authors_params(xlsm, converted):
    """converted: set of (robot, path, session) present in the output."""
    sheets = read_xlsx(xlsm)
    out = {}
    spec = [("diff-Sousa", "diff"), ("diff-UMBmark", "diff"), ("omni3-sousa", "omni3"), ("omni4-sousa", "omni4")]
    for sheet, robot in spec:
        rows = sheets[sheet]
        entries = []
        note_section = ""
        last = None
        for rn in sorted(rows):
            row = rows[rn]
            a = row.get("A")
            if not isinstance(a, str):
                continue
            if a.startswith("article"):
                note_section = a
                continue
            m = re.match(r"(\w+)/(\w+)/(\d+)/\d+$", a)
            note = note_section
            if m:
                rb, path, session = m.groups()
                last = (rb, path, session)
            else:
                mw = re.match(r"\(without worse runs: (\d+)\)$", a)
                if not (mw and last):
                    last = None
                    continue
                rb, path, session = last
                note = "without run %s" % mw.group(1)
            if (rb, path, session) not in converted:
                continue
            e = build_entry(robot, row, rows, rn, session, path, note)
            if e is not None:
                entries.append(e)
        out[sheet] = entries
    return out


def _f(row, col):
    v = row.get(col)
    return float(v) if isinstance(v, float) else None


def build_entry(robot, row, rows, rn, session, path, note):
    def measures(cols):
        vals = [_f(row, c) for c in cols]
        if any(v is None for v in vals):
            return None
        return dict(zip(["max_pos_err_m", "max_heading_err_deg", "max_final_pos_err_m",
                         "max_final_heading_err_deg"], vals))

    if robot == "diff":
        b, dR, dL = _f(row, "I"), _f(row, "J"), _f(row, "K")
        if None in (b, dR, dL):
            return None
        runs = _f(row, "P")
        return {"session": session, "path": path, "note": note, "D_R": dR, "D_L": dL, "b": b,
                "unit": "m", "runs": int(runs) if runs is not None else None, "sheet_row": rn,
                "initial": {"D_R": _f(row, "C"), "D_L": _f(row, "D"), "b": _f(row, "B")}}
    if robot == "omni3":
        L = _f(row, "J")
        D = [_f(row, c) for c in "KLM"]
        if L is None or None in D:
            return None
        L0, D0 = _f(row, "B"), [_f(row, c) for c in "CDE"]
        runs = _f(row, "R")
        return {"session": session, "path": path, "note": note, "robot": "omni3", "unit": "m",
                "runs": int(runs) if runs is not None else None, "sheet_row": rn,
                "authors": {"L": L, "D": D}, "wheels": omni3_wheels(L, D),
                "initial": {"authors": {"L": L0, "D": D0}, "wheels": omni3_wheels(L0, D0)},
                "measures_before": measures("FGHI"), "measures_after": measures("NOPQ")}
    L1, L2 = _f(row, "M"), _f(row, "N")
    D = [_f(row, c) for c in "PQRS"]
    if None in (L1, L2) or None in D:
        return None
    L12 = _f(row, "O")
    if L12 is None:
        L12 = L1 + L2
    a1, a2 = _f(row, "B"), _f(row, "C")
    a12 = _f(row, "D") if _f(row, "D") is not None else a1 + a2
    D0 = [_f(row, c) for c in "EFGH"]
    runs = _f(row, "X")
    return {"session": session, "path": path, "note": note, "robot": "omni4", "unit": "m",
            "runs": int(runs) if runs is not None else None, "sheet_row": rn,
            "authors": {"L1": L1, "L2": L2, "L1+L2": L12, "D": D}, "wheels": omni4_wheels(L12, D),
            "initial": {"authors": {"L1": a1, "L2": a2, "L1+L2": a12, "D": D0},
                        "wheels": omni4_wheels(a12, D0)},
            "measures_before": measures("IJKL"), "measures_after": measures("TUVW")}


# The folder's README.md (written as is).
README = """# Real sessions: many runs of three real robots (OptiOdom dataset)

299 runs in 45 sessions, converted to `../../spec/formats.md` (robot.toml + recording.csv),
one folder per run: `<robot>-<path>-<session>-run-NN`. Source: the OptiOdom dataset,
GitHub `sousarbarb/optiodom` at commit 8e025fd7a30c (R. B. Sousa, M. R. Petry, P. G. Costa,
A. P. Moreira, J. Intell. Robot. Syst. 105, 39, 2022; MIT licence, Copyright (c) 2021 the
authors). Data only, re-expressed in our column layout. The six folders `../diff-square-run-0N`
are the same runs as `diff-square-231220200029-run-0N` here.

| robot | path kinds here (sessions / runs) |
|---|---|
| `diff`: differential drive, 84 mm wheels, 0.200 m separation, 43.7:1 gear, 64 counts per motor rev | square 8 / 44, circular 13 / 54, ivanjko 8 / 66 |
| `omni3`: three omni wheels, 102 mm, 0.195 m from the centre | square 2 / 23, circular 7 / 44 |
| `omni4`: four mecanum wheels, published 60 mm | square 4 / 44, circular 3 / 24 (September 2020) |

Session ids are DDMMYYYYhhmm: 23 June 2020, 25 June 2020, 22 and 23 December 2020, 8 September
2020. `index.csv` has a row per run: path kind, direction (cw/ccw from the true end heading),
rows, duration, the nominal geometry's end, max and RMS position error dead-reckoned from the
first row, the heading error at the start, and the session's controller parameters.

Facts to know:
- Ground truth is motion capture of the robot's kinematic centre in the robot's start frame:
  the first row is exactly (0, 0, 0) by construction, so the start pose is known, not a
  parameter to fit. The authors' own method (OptiOdom) integrates odometry from that start
  with no resets and compares positions every 0.5 m of travel.
- `t` is the nominal cycle count times the nominal cycle; the real cycle was longer (diff
  1.8-2.6 %, omni3 1.0-2.2 %, omni4 6-12 %; column `stretch_real_over_nominal`). Positions
  agree; rates computed from `t` are high by that much.
- Six diff sessions (23 and 25 June 2020, see `controller_params_wrong`) were driven with
  deliberately wrong controller geometry. The counts are raw, so with the true geometry
  written here they are ordinary recordings; only the commanded path differs.
- Things a robust method must survive: run 02 of square 231220200029 starts with a turn in
  place where odometry turns -0.13 rad and motion capture -0.05 rad (the wheels slipped);
  counter-clockwise Ivanjko spins of 23 December start with motion capture leading the
  odometry by about 0.1 s; the counter-clockwise circles of 23 December end 136-159 mm off
  with the nominal geometry, the clockwise ones 65-85 mm.
- The mecanum robot behaves as if its wheels were about 67 mm, not the published 60 mm.
- `authors_params.json`: the OptiOdom authors' own calibrated parameters per session, in metres.
  - `diff-Sousa` (OptiOdom) and `diff-UMBmark` (UMBmark): D_R and D_L are the right and left
    wheel diameters, b the separation.
  - `omni3-sousa` and `omni4-sousa`: the authors' numbers, and `wheels` in our robot.toml
    convention. Wheel i is their D_i; for the mecanum robot, L1 + L2 is wheelbase plus track,
    and only their sum enters.
  - `runs` is how many runs of the session each row was fitted on.
  Use them as the anchor to beat: replay a run with them and with yours, from the first row.
- Other runs of these robots (free-form drives of the differential robot, a joystick-driven
  omni3, omni4 circles of December 2020 and one omni4 square session) are kept apart to check results on motion
  no one tuned to.
"""


# --------------------------------------------------------------------------- driver

INDEX_COLS = ["folder", "robot", "path", "session", "run", "direction", "rows", "duration_s",
              "nominal_end_pos_err_m", "nominal_max_pos_err_m", "nominal_rms_pos_err_m",
              "nominal_end_heading_err_rad", "gt_end_heading_rad", "gt_path_m",
              "stretch_real_over_nominal", "start_heading_err_rad", "controller_params",
              "controller_params_wrong", "fk_max_abs_diff", "notes"]


def fmt_param(v):
    return repr(float(v))


def convert(src, out, log=print):
    data = os.path.join(src, "data")
    if not os.path.isdir(data):
        die("%s has no data/ folder: not an OptiOdom checkout" % src)
    xlsm = os.path.join(data, "data.xlsm")
    if not os.path.isfile(xlsm):
        die("missing %s (the authors' parameters)" % xlsm)
    index = []
    converted = set()
    written = 0
    for robot, paths in ROBOTS.items():
        for path in paths:
            pdir = os.path.join(data, robot, path)
            if not os.path.isdir(pdir):
                die("missing %s" % pdir)
            for session in sorted(os.listdir(pdir)):
                if kept_apart(robot, path, session):
                    continue
                sdir = os.path.join(pdir, session)
                md_path = os.path.join(sdir, session + "_metadata.csv")
                if not os.path.isfile(md_path):
                    die("missing %s" % md_path)
                md = read_metadata(md_path)
                logf = read_session_log(os.path.join(sdir, session + ".csv"))
                wheels, gear, cpr = robot_geometry(robot, md)
                nw = len(wheels)
                # Session controller parameters.
                wrong = ""
                if robot == "diff":
                    if logf is None:
                        die("missing the diff session log %s.csv" % os.path.join(sdir, session))
                    p = dict(logf["params"])
                    ctrl = [(k, fmt_param(p[k])) for k in ("dL0", "dR0", "b0")]
                    ctrl_csv = ";".join("%s=%s" % kv for kv in ctrl)
                    is_wrong = (p["dL0"], p["dR0"], p["b0"]) != (DIFF_D, DIFF_D, DIFF_B)
                    wrong = "yes" if is_wrong else "no"
                    ctrl_txt = ctrl
                elif logf is not None and logf["params"]:
                    ctrl_csv = ";".join("%s=%s" % (k, fmt_param(v)) for k, v in logf["params"])
                    ctrl_txt = ctrl_csv
                    is_wrong = False
                else:
                    li, di = md["Li"], md["Di"]
                    ctrl_csv = "log absent; metadata " + ";".join(
                        ["L%d=%s" % (i + 1, v) for i, v in enumerate(li)] +
                        ["D%d=%s" % (i + 1, v) for i, v in enumerate(di)])
                    ctrl_txt = ctrl_csv
                    is_wrong = False
                runs = sorted(int(m.group(1)) for m in
                              (re.match(re.escape(session) + r"_run-(\d+)\.csv$", f) for f in os.listdir(sdir)) if m)
                for k, runno in enumerate(runs):
                    run = "%02d" % runno
                    src_rows = read_rows(os.path.join(sdir, "%s_run-%s.csv" % (session, run)))
                    rows, incs, notes = convert_run(robot, src_rows, nw)
                    # stretch: real (motion capture) span over the nominal (odometry) span.
                    stretch = ""
                    try:
                        gti, gtf = float(md["gt_ti"][runno - 1]), float(md["gt_tf"][runno - 1])
                        oti, otf = float(md["odo_ti"][runno - 1]), float(md["odo_tf"][runno - 1])
                        stretch = (gtf - gti) / (otf - oti)
                    except (KeyError, IndexError, ValueError, ZeroDivisionError):
                        pass
                    st = run_stats(robot, md, rows, incs, wheels, cpr)
                    gth = st["gt_end_head"]
                    direction = "" if abs(gth) < math.pi / 2 else ("cw" if gth < 0 else "ccw")
                    if st["fk"] > 1e-9:
                        notes.append("fk |diff| %.2e against the printed revolutions, which lie up to %.1e "
                                     "counts off the 1/11520 grid; %.1e on the grid"
                                     % (st["fk"], st["off_grid"], st["fk_grid"]))
                    if st["start"] > 0.05:
                        notes.append("start heading error %.3f rad within 1 s" % st["start"])
                    if robot == "diff" and is_wrong and logf and runno in logf["runs"]:
                        e_ctrl = log_replay_error(robot, logf["runs"][runno], (p["dL0"], p["dR0"], p["b0"]))
                        e_nom = log_replay_error(robot, logf["runs"][runno], (DIFF_D, DIFF_D, DIFF_B))
                        notes.append("on-board log vs controller parameters %.1e, vs true nominal %.1e"
                                     % (e_ctrl, e_nom))
                    folder = "%s-%s-%s-run-%s" % (robot, path, session, run)
                    fdir = os.path.join(out, folder)
                    os.makedirs(fdir)
                    with open(os.path.join(fdir, "robot.toml"), "w", newline="\n") as f:
                        f.write(robot_toml(robot, path, session, run, direction, md, ctrl_txt, is_wrong))
                    names = [w["name"] for w in wheels]
                    with open(os.path.join(fdir, "recording.csv"), "w", newline="\n") as f:
                        f.write(",".join(["t"] + ["enc_" + n for n in names] + ["x", "y", "theta"]) + "\n")
                        for tt, cum, pose in rows:
                            f.write(",".join([tt] + [str(c) for c in cum] + list(pose)) + "\n")
                    index.append([folder, robot, path, session, run, direction, str(st["rows"]),
                                  "%.2f" % st["duration"], g6(st["end_err"]), g6(st["max_err"]),
                                  g6(st["rms"]), g6(st["end_head"]), g6(gth), g6(st["gt_path"]),
                                  g6(stretch) if stretch != "" else "", g6(st["start"]), ctrl_csv, wrong,
                                  g6(st["fk"]), " | ".join(notes)])
                    converted.add((robot, path, session))
                    written += 1
    index.sort(key=lambda r: r[0])
    with open(os.path.join(out, "index.csv"), "w", newline="") as f:
        w = csv.writer(f)  # csv default: CRLF line ends, as the reference folder has
        w.writerow(INDEX_COLS)
        w.writerows(index)
    ap = authors_params(xlsm, converted)
    with open(os.path.join(out, "authors_params.json"), "w") as f:
        json.dump(ap, f, indent=1)
    log("converted %d runs in %d sessions" % (written, len(converted)))
    return written


# --------------------------------------------------------------------------- compare

def compare(out, ref, rel=1e-9):
    """Print per-run max differences between two converted folders; return True if equal."""
    ok = True
    a = {d for d in os.listdir(out) if "-run-" in d}
    b = {d for d in os.listdir(ref) if "-run-" in d}
    only_a, only_b = sorted(a - b), sorted(b - a)
    if only_a:
        ok = False
        print("only in %s (%d): %s" % (out, len(only_a), " ".join(only_a)))
    if only_b:
        ok = False
        print("only in %s (%d): %s" % (ref, len(only_b), " ".join(only_b)))
    exact = toml_bad = csv_bad = 0
    total_max = 0.0
    for d in sorted(a & b):
        ta = parse_toml(os.path.join(out, d, "robot.toml"))
        tb = parse_toml(os.path.join(ref, d, "robot.toml"))
        ca = comments(os.path.join(out, d, "robot.toml"))
        cb = comments(os.path.join(ref, d, "robot.toml"))
        toml_ok = ta == tb
        cm_ok = ca == cb
        worst, why = csv_diff(os.path.join(out, d, "recording.csv"), os.path.join(ref, d, "recording.csv"), rel)
        total_max = max(total_max, worst)
        if not toml_ok:
            toml_bad += 1
        if why or worst > rel:
            csv_bad += 1
        if toml_ok and cm_ok and not why and worst <= rel:
            exact += 1
        else:
            print("%s: robot.toml %s, comments %s, recording max rel diff %.3g %s"
                  % (d, "same" if toml_ok else "DIFFERS", "same" if cm_ok else "differ", worst, why))
    print("runs compared: %d; identical (robot.toml values and comments, recording within %g): %d; "
          "robot.toml differs: %d; recording differs: %d; largest recording rel diff %.3g"
          % (len(a & b), rel, exact, toml_bad, csv_bad, total_max))
    ok = ok and exact == len(a & b)
    for name in ("README.md",):
        pa, pb = os.path.join(out, name), os.path.join(ref, name)
        same = os.path.isfile(pa) and os.path.isfile(pb) and open(pa).read() == open(pb).read()
        print("%s: %s" % (name, "identical" if same else "DIFFERS"))
        ok = ok and same
    ok = compare_index(out, ref, rel) and ok
    ok = compare_json(out, ref, rel) and ok
    return ok


def comments(path):
    with open(path) as f:
        return [l.rstrip("\n") for l in f if l.startswith("#")]


def parse_toml(path):
    """Enough TOML for robot.toml: top-level keys, tables, arrays of tables."""
    doc = {}
    cur = doc
    with open(path) as f:
        for line in f:
            line = line.split("#", 1)[0].strip() if not line.lstrip().startswith("#") else ""
            if not line:
                continue
            if line.startswith("[["):
                name = line.strip("[]")
                cur = {}
                doc.setdefault(name, []).append(cur)
            elif line.startswith("["):
                cur = {}
                doc[line.strip("[]")] = cur
            else:
                k, v = (s.strip() for s in line.split("=", 1))
                if v.startswith('"'):
                    v = v.strip('"')
                elif v in ("true", "false"):
                    v = v == "true"
                else:
                    v = float(v)
                cur[k] = v
    return doc


def rel_diff(x, y):
    if x == y:
        return 0.0
    return abs(x - y) / max(abs(x), abs(y))


def csv_diff(pa, pb, rel):
    with open(pa) as f:
        A = list(csv.reader(f))
    with open(pb) as f:
        B = list(csv.reader(f))
    if A[0] != B[0]:
        return float("inf"), "(header %s vs %s)" % (A[0], B[0])
    if len(A) != len(B):
        return float("inf"), "(rows %d vs %d)" % (len(A) - 1, len(B) - 1)
    worst = 0.0
    for ra, rb in zip(A[1:], B[1:]):
        for x, y in zip(ra, rb):
            worst = max(worst, rel_diff(float(x), float(y)))
    return worst, ""


NOISE = re.compile(r"\d(\.\d+)?e-(1[5-9]|[2-9]\d)")


def compare_index(out, ref, rel):
    def load(p):
        with open(os.path.join(p, "index.csv")) as f:
            return {r["folder"]: r for r in csv.DictReader(f)}
    A, B = load(out), load(ref)
    cols = INDEX_COLS[1:]
    bad = {}
    worst = {}
    for k in sorted(set(A) & set(B)):
        for c in cols:
            x, y = A[k].get(c, ""), B[k].get(c, "")
            if c == "notes":
                x, y = NOISE.sub("<1e-15>", x), NOISE.sub("<1e-15>", y)
            try:
                if c == "fk_max_abs_diff" and max(abs(float(x)), abs(float(y))) < 1e-15:
                    continue  # both float rounding noise: not reproducible digit for digit
                d = rel_diff(float(x), float(y))
                worst[c] = max(worst.get(c, 0.0), d)
                if d > rel:
                    bad.setdefault(c, []).append(k)
            except ValueError:
                if x != y:
                    bad.setdefault(c, []).append(k)
    print("index.csv: %d rows vs %d (fk_max_abs_diff values below 1e-15 on both sides count as equal:"
          " float rounding noise); columns that differ:" % (len(A), len(B)))
    for c in cols:
        if c in bad:
            print("  %-28s %3d rows differ (max rel %.3g), e.g. %s: %r vs %r"
                  % (c, len(bad[c]), worst.get(c, float("nan")), bad[c][0], A[bad[c][0]][c], B[bad[c][0]][c]))
    if not bad:
        print("  none")
    return not bad and set(A) == set(B)


def compare_json(out, ref, rel):
    with open(os.path.join(out, "authors_params.json")) as f:
        A = json.load(f)
    with open(os.path.join(ref, "authors_params.json")) as f:
        B = json.load(f)
    diffs = []

    def walk(a, b, where):
        if isinstance(a, dict) and isinstance(b, dict):
            for k in sorted(set(a) | set(b)):
                if k not in a or k not in b:
                    diffs.append("%s.%s missing on one side" % (where, k))
                else:
                    walk(a[k], b[k], "%s.%s" % (where, k))
        elif isinstance(a, list) and isinstance(b, list):
            if len(a) != len(b):
                diffs.append("%s: %d vs %d entries" % (where, len(a), len(b)))
            for i, (x, y) in enumerate(zip(a, b)):
                walk(x, y, "%s[%d]" % (where, i))
        elif isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
            if rel_diff(a, b) > rel:
                diffs.append("%s: %r vs %r" % (where, a, b))
        elif a != b:
            diffs.append("%s: %r vs %r" % (where, a, b))
    walk(A, B, "")
    print("authors_params.json: %s" % ("equivalent" if not diffs else "%d differences" % len(diffs)))
    for d in diffs[:20]:
        print("  " + d)
    return not diffs


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--src", help="an OptiOdom checkout (at commit %s)" % COMMIT_SHORT)
    ap.add_argument("--out", required=True, help="the converted folder (must not exist when converting)")
    ap.add_argument("--compare", metavar="REF_DIR", help="compare OUT with a reference converted folder")
    a = ap.parse_args()
    if a.src:
        if os.path.exists(a.out) and os.listdir(a.out):
            die("%s exists and is not empty" % a.out)
        os.makedirs(a.out, exist_ok=True)
        convert(a.src, a.out)
        with open(os.path.join(a.out, "README.md"), "w", newline="\n") as g:
            g.write(README)
    if a.compare:
        sys.exit(0 if compare(a.out, a.compare) else 2)


if __name__ == "__main__":
    main()
