#!/usr/bin/env bash
# Fetches the OptiOdom dataset and converts it into wheelcal's real-sessions folder
# (the layout the ignored `sessions` tests read through WHEELCAL_SESSIONS; see
# data/real/README.md).
#
# Provenance: the OptiOdom dataset, GitHub sousarbarb/optiodom at commit
# 8e025fd7a30c7152132e0ae53ba23bbc909f5a81, by Ricardo B. Sousa, Marcelo R. Petry,
# Paulo G. Costa and A. Paulo Moreira, "OptiOdom: a Generic Approach for Odometry
# Calibration of Wheeled Mobile Robots", J. Intell. Robot. Syst. 105, 39 (2022),
# https://doi.org/10.1007/s10846-022-01630-3. MIT licence, Copyright (c) 2021 the
# authors. Data only is taken, re-expressed in wheelcal's column layout.
#
# What the conversion does (scripts/optiodom_sessions.py has the details): one folder
# per run, <robot>-<path>-<session>-run-NN, with robot.toml (the nominal geometry in the
# Siegwart convention of docs/formats.md) and recording.csv (t, cumulative encoder
# counts, motion-capture pose in the robot's start frame, one row per odometry cycle,
# as the authors synchronised them); plus index.csv, authors_params.json (the authors'
# calibrated parameters from data/data.xlsm, in metres) and README.md. Runs kept apart
# as held-out data (diff free drives, omni3 joystick drives, the omni4 circles of
# December 2020 and omni4 square session 080920201205) are not converted.
#
# Usage:
#   bash scripts/fetch-sessions.sh [--force] [--from CHECKOUT] OUT_DIR
#     --from CHECKOUT  convert an existing checkout of the dataset (no network)
#     --force          replace a non-empty OUT_DIR
# Needs git (unless --from), python3 (standard library only) and, without --from,
# access to github.com. Output is built in a temporary folder beside OUT_DIR and moved
# into place only when the whole conversion succeeded.
set -euo pipefail

COMMIT=8e025fd7a30c7152132e0ae53ba23bbc909f5a81
REPO_URL=https://github.com/sousarbarb/optiodom.git
HERE=$(cd "$(dirname "$0")" && pwd)
CONVERTER=$HERE/optiodom_sessions.py

die() { echo "fetch-sessions: error: $*" >&2; exit 1; }
usage() { sed -n '/^# Usage:/,/^# Needs/p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2; }

force=0
from=
out=
while [ $# -gt 0 ]; do
  case "$1" in
    --force) force=1 ;;
    --from) [ $# -ge 2 ] || usage; from=$2; shift ;;
    --from=*) from=${1#--from=} ;;
    -h|--help) usage ;;
    -*) echo "fetch-sessions: unknown option $1" >&2; usage ;;
    *) [ -z "$out" ] || usage; out=$1 ;;
  esac
  shift
done
[ -n "$out" ] || usage

# Requirements first: nothing is written before they are all met.
command -v python3 >/dev/null 2>&1 || die "python3 is missing (it runs the converter; standard library only)"
pyver=$(python3 -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null) \
  || die "python3 is on PATH but does not run"
python3 -c 'import sys; sys.exit(0 if sys.version_info >= (3, 6) else 1)' \
  || die "python3 is $pyver; the converter needs 3.6 or newer"
[ -f "$CONVERTER" ] || die "the converter $CONVERTER is missing"
if [ -z "$from" ]; then
  command -v git >/dev/null 2>&1 || die "git is missing (needed to clone $REPO_URL; or pass --from CHECKOUT)"
else
  [ -d "$from/data" ] || die "--from $from: no data/ folder there, not an OptiOdom checkout"
fi
if [ -e "$out" ] && [ ! -d "$out" ]; then
  die "$out exists and is not a folder"
fi
if [ -d "$out" ] && [ -n "$(ls -A "$out")" ] && [ "$force" != 1 ]; then
  die "$out is not empty; pass --force to replace it"
fi

parent=$(dirname "$out")
mkdir -p "$parent"
stage=$(mktemp -d "$parent/.fetch-sessions.XXXXXX")
clone=
cleanup() {
  rm -rf "$stage"
  [ -z "$clone" ] || rm -rf "$clone"
}
trap cleanup EXIT

if [ -z "$from" ]; then
  clone=$(mktemp -d "${TMPDIR:-/tmp}/optiodom.XXXXXX")
  echo "fetching $REPO_URL at $COMMIT into $clone (about 1.2 GB of data)" >&2
  git -C "$clone" init -q
  git -C "$clone" remote add origin "$REPO_URL"
  if ! git -C "$clone" fetch -q --depth 1 origin "$COMMIT" 2>"$clone.err"; then
    # Some servers refuse fetching a commit by id; fall back to the whole history.
    if ! git -C "$clone" fetch -q origin 2>>"$clone.err"; then
      cat "$clone.err" >&2; rm -f "$clone.err"
      die "cannot fetch $REPO_URL: no network access to github.com? (or pass --from CHECKOUT)"
    fi
  fi
  rm -f "$clone.err"
  git -C "$clone" -c advice.detachedHead=false checkout -q "$COMMIT" \
    || die "commit $COMMIT not found in $REPO_URL"
  from=$clone
elif git -C "$from" rev-parse --verify -q HEAD >/dev/null 2>&1; then
  head=$(git -C "$from" rev-parse HEAD)
  [ "$head" = "$COMMIT" ] || echo "fetch-sessions: warning: $from is at $head, not the pinned $COMMIT" >&2
fi

python3 "$CONVERTER" --src "$from" --out "$stage" >&2 || die "the conversion failed; $out is unchanged"

if [ -d "$out" ]; then
  rm -rf "$out"
fi
mv "$stage" "$out"
echo "converted into $out" >&2
echo "export WHEELCAL_SESSIONS=$(cd "$out" && pwd)"
