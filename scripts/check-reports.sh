#!/usr/bin/env bash
# Every kind of HTML report, written from the real recordings in data/real and checked in
# a real browser (headless Chromium, 1400 px wide): no sideways scroll, every plot loads,
# the answer (verdict or factors, in a table) on the first screen (1400 x 1000).
# Screenshots of each page land in OUT_DIR (default target/report-check) for a person to
# look at. Needs Debian's chromium (apt-get install -y chromium) and python3.
#
#   bash scripts/check-reports.sh [OUT_DIR]
#
# The reports:
#   diagnose-diff   diagnose of diff-square-run-01 (a real UMBmark square)
#   diagnose-omni3  diagnose of omni3-square-run-01
#   calibrate-diff  calibrate on squares 01, 02, 04, 05 (cw and ccw), 03 held out
#   calibrate-omni3 calibrate on omni3-square-run-01
#   umbmark         umbmark compute on the six squares' end errors: measured minus the
#                   nominal robot's dead reckoning (before) and minus calibrate-diff's
#                   fitted robot's (after), from evaluate --tum
#   omni            omni compute on a small runs file written here: data/real holds no
#                   straight-path (4W-1/4W-2) runs, so these end errors are made up (a
#                   radial error of 20-40 mm before, a tenth after); the page is what is
#                   checked, not the numbers
set -euo pipefail
cd "$(dirname "$0")/.."
OUT="${1:-${CARGO_TARGET_DIR:-target}/report-check}"
command -v chromium >/dev/null || command -v chromium-browser >/dev/null || {
  echo "check-reports: no chromium; install it: apt-get install -y chromium" >&2
  exit 1
}
cargo build --locked -q -p wheelcal
W="$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')/debug/wheelcal"
rm -rf "$OUT"
mkdir -p "$OUT"
# The commands' notes go to a log, shown when one fails.
LOG="$OUT/commands.log"
trap 'rc=$?; [ $rc = 0 ] || { echo "check-reports: failed; the commands said:" >&2; cat "$LOG" >&2; }' EXIT
exec 3>&2 2>>"$LOG"
R=data/real
DIFF=$R/diff-square-run-01/robot.toml
OMNI=$R/omni3-square-run-01/robot.toml

"$W" diagnose --robot "$DIFF" --recording $R/diff-square-run-01 --report "$OUT/diagnose-diff" >/dev/null
"$W" diagnose --robot "$OMNI" --recording $R/omni3-square-run-01 --report "$OUT/diagnose-omni3" >/dev/null
"$W" calibrate --robot "$DIFF" --recording $R/diff-square-run-01 --recording $R/diff-square-run-02 \
  --recording $R/diff-square-run-04 --recording $R/diff-square-run-05 \
  --holdout $R/diff-square-run-03 --report "$OUT/calibrate-diff" >/dev/null
"$W" calibrate --robot "$OMNI" --recording $R/omni3-square-run-01 --report "$OUT/calibrate-omni3" >/dev/null

# UMBmark end errors from the real squares (cw: 01-03, ccw: 04-06; 1.7 m sides).
squares=()
for i in 1 2 3 4 5 6; do squares+=(--recording "$R/diff-square-run-0$i"); done
"$W" evaluate --robot "$DIFF" "${squares[@]}" --tum "$OUT/tum-before" >/dev/null
"$W" evaluate --robot "$OUT/calibrate-diff/robot.toml" "${squares[@]}" --tum "$OUT/tum-after" >/dev/null
python3 - "$OUT" <<'EOF'
import glob, os, sys
out = sys.argv[1]
def last(path):
    rows = [l.split() for l in open(path) if l.strip() and not l.startswith("#")]
    return float(rows[-1][1]), float(rows[-1][2])
lines = ["test,path,length_m,x_err_m,y_err_m,theta_err_rad,phase"]
for phase in ("before", "after"):
    for i in range(1, 7):
        rec = f"diff-square-run-0{i}"
        d = os.path.join(out, f"tum-{phase}")
        mx, my = last(os.path.join(d, f"{rec}__measured.txt"))
        (odo,) = [f for f in glob.glob(os.path.join(d, f"{rec}__1_*.txt"))]
        ox, oy = last(odo)
        lines.append(f"umbmark,{'cw' if i <= 3 else 'ccw'},1.7,{mx - ox:.6f},{my - oy:.6f},,{phase}")
open(os.path.join(out, "umbmark-runs.csv"), "w").write("\n".join(lines) + "\n")
EOF
"$W" umbmark compute --robot "$DIFF" --runs "$OUT/umbmark-runs.csv" --report "$OUT/umbmark" >/dev/null

# Omni: made-up straight-path runs (see above).
python3 - "$OUT" <<'EOF'
import math, os, sys
lines = ["test,path,length_m,x_err_m,y_err_m,theta_err_rad,phase"]
for path in ("4W-1", "4W-2"):
    for k in range(6):
        e = 0.02 + 0.004 * k
        a = 0.3 * math.sin(1.7 * k)
        lines.append(f"omni,{path},0.6,{-e * math.cos(a):.6f},{e * math.sin(a):.6f},,before")
        lines.append(f"omni,{path},0.6,{-e * math.cos(a) / 10:.6f},{e * math.sin(a) / 10:.6f},,after")
open(os.path.join(sys.argv[1], "omni-runs.csv"), "w").write("\n".join(lines) + "\n")
EOF
"$W" omni compute --robot "$OMNI" --runs "$OUT/omni-runs.csv" --report "$OUT/omni" >/dev/null

pages=()
for name in diagnose-diff diagnose-omni3 calibrate-diff calibrate-omni3 umbmark omni; do
  pages+=("$name=$OUT/$name/index.html")
done
exec 2>&3
python3 scripts/check_reports.py "$OUT/screenshots" "${pages[@]}"
echo "screenshots: $OUT/screenshots"
