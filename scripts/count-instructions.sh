#!/usr/bin/env bash
# Counts the instructions a procedure's demo takes on one thread, under valgrind's cachegrind:
# a figure that repeats on a busy shared machine, where wall-clock timings swing by a third
# from hour to hour. Use it to check a speed claim on such a machine: count the build before
# and the build after, and compare. The session's state hash is printed beside the count, so a
# change meant to keep the bytes shows that it did.
#
#   scripts/count-instructions.sh PROCEDURE [run options...]
#   scripts/count-instructions.sh rectum --preset cpu
#
# Environment: VESALIUS, the binary (default target/release/vesalius, built with
# `cargo build --release`); TOP, how many functions to list (default 20); KEEP, a folder to
# keep cachegrind's output in (default: removed). Needs valgrind (Debian: valgrind) and
# python3. A demo runs about 20 to 50 times slower under cachegrind than alone: the rectum's
# preset demo takes about 40 s here, the sandbox's about 35 s.
set -euo pipefail

if [ $# -lt 1 ]; then
    echo "usage: $0 PROCEDURE [run options...]   (e.g. $0 rectum --preset cpu)" >&2
    exit 2
fi
proc=$1
shift
bin=${VESALIUS:-target/release/vesalius}
top=${TOP:-20}
trace="assets/traces/${proc}-demo.toml"
for tool in valgrind cg_annotate python3; do
    if ! command -v "$tool" > /dev/null; then
        echo "$0: $tool is missing (Debian: apt-get install valgrind python3)" >&2
        exit 2
    fi
done
if [ ! -x "$bin" ]; then
    echo "$0: no binary at $bin (cargo build --release, or set VESALIUS)" >&2
    exit 2
fi
if [ ! -f "$trace" ]; then
    echo "$0: no demo trace for '$proc' at $trace" >&2
    exit 2
fi

work=$(mktemp -d)
if [ -n "${KEEP:-}" ]; then
    mkdir -p "$KEEP"
    work_out=$KEEP
else
    work_out=$work
    trap 'rm -rf "$work"' EXIT
fi

echo "counting: $bin --threads 1 run $proc --headless --trace $trace $*" >&2
valgrind --tool=cachegrind --cache-sim=no --cachegrind-out-file="$work_out/cachegrind.out" \
    "$bin" --threads 1 run "$proc" --headless --trace "$trace" --out "$work_out/run" "$@" \
    > "$work_out/run.log" 2>&1 || {
    echo "$0: the run failed; its output:" >&2
    tail -20 "$work_out/run.log" >&2
    exit 1
}
cg_annotate --auto=no --threshold=0.01 "$work_out/cachegrind.out" > "$work_out/annotated.txt"

python3 - "$work_out/annotated.txt" "$work_out/run/report.json" "$proc" "$top" <<'PY'
import collections, json, re, sys

annotated, report, proc, top = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
by_function = collections.Counter()
total = None
for line in open(annotated):
    m = re.match(r"\s*([\d,]+)(?: \(\s*[\d.]+%\))?\s+PROGRAM TOTALS", line)
    if m:
        total = int(m.group(1).replace(",", ""))
        continue
    m = re.match(r"\s*([\d,]+)(?: \(\s*[\d.]+%\))?\s+[^\s:][^:]*:(.*)$", line)
    if m:
        by_function[m.group(2).strip()] += int(m.group(1).replace(",", ""))
if total is None:
    sys.exit("count-instructions: cachegrind's totals were not found in its output")
try:
    state_hash = json.load(open(report)).get("state_hash")
except (OSError, ValueError):
    state_hash = None
print(json.dumps({"procedure": proc, "instructions": total, "state_hash": state_hash}))
for name, n in by_function.most_common(top):
    print(f"{n / 1e6:10.1f} M {100 * n / total:6.2f} %  {name[:110]}")
PY
