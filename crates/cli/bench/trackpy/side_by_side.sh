#!/usr/bin/env bash
# physfit track against trackpy 0.7 (numba) on the same frames, one thread each, one machine:
# prints a Markdown table of seconds, tracks and the ratio at N = 10, 100 and 1000 discs.
# trackpy is installed in a throwaway virtual environment (PyPI), removed afterwards; nothing
# is installed into the project or the system. Usage: side_by_side.sh [FRAMES] (default 200).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../../../.." && pwd)"
frames="${1:-200}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
python3 -m venv "$work/venv"
"$work/venv/bin/pip" install -q trackpy numba pillow
(cd "$root" && cargo build --release -q)
# Where cargo put it: CARGO_TARGET_DIR when set (a worktree with its own target directory).
physfit="${CARGO_TARGET_DIR:-$root/target}/release/physfit"
echo "| particles | frames | physfit (s) | physfit tracks | physfit identity switches | trackpy (s) | trackpy tracks | trackpy / physfit |"
echo "|---:|---:|---:|---:|---:|---:|---:|---:|"
for n in 10 100 1000; do
  "$work/venv/bin/python" "$here/frames.py" "$n" "$frames" "$work/n$n"
  # Best of three for each, one thread.
  best_p=""; best_t=""
  for _ in 1 2 3; do
    t0=$(date +%s.%N)
    RAYON_NUM_THREADS=1 "$physfit" -q track "$work/n$n/frames" --out "$work/n$n/tracks.csv"
    t1=$(date +%s.%N)
    p=$(echo "$t1 - $t0" | bc -l)
    if [ -z "$best_p" ] || [ "$(echo "$p < $best_p" | bc -l)" = 1 ]; then best_p=$p; fi
    read -r t tracks_t < <(NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 "$work/venv/bin/python" "$here/trackpy_run.py" "$work/n$n/frames")
    if [ -z "$best_t" ] || [ "$(echo "$t < $best_t" | bc -l)" = 1 ]; then best_t=$t; fi
  done
  tracks_p=$(tail -n +2 "$work/n$n/tracks.csv" | cut -d, -f2 | sort -u | wc -l)
  # Scored against the drawn walks (not timed): a track that changes particle counts.
  switches_p=$("$physfit" track "$work/n$n/frames" --truth "$work/n$n/truth.csv" --out "$work/n$n/scored.csv" 2>&1 \
    | awk -F'|' '/identity switches/ {gsub(/ /, "", $3); print $3}')
  printf "| %d | %d | %.3f | %d | %s | %.3f | %d | %.1fx |\n" "$n" "$frames" "$best_p" "$tracks_p" "$switches_p" "$best_t" "$tracks_t" \
    "$(echo "$best_t / $best_p" | bc -l)"
done
