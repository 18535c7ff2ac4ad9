#!/bin/sh
# CPU time per frame of the global-shutter sequence of `bench_sequence` (issue 34), split
# by the part of the frame that spends it, for one or more builds of the example, run in
# turn; BENCHMARKS.md round 23. On a shared machine the wall clock of the benchmark moves
# with the other jobs; the CPU samples of the sequence's own threads move less.
#
#   sh benches/sequence_cpu.sh BENCH_SEQUENCE_BINARY...
#
# Each binary runs `1024:64:64` once (EOIR_BENCH_REPEAT=1) under `perf record` (cpu-clock,
# 4 kHz). The sequence's window runs from the first sample in the path blur's columns
# (frame 0 of the moving camera, after its spectrum was accumulated) to the last sample
# in the blur or the detector's rows before the rolling-shutter run starts accumulating;
# the samples in it over 4000 Hz and 64 frames give ms of CPU per frame. Needs `perf`
# and `python3`; the binaries must keep their symbols (the release profile does).
set -eu
[ $# -gt 0 ] || { echo "usage: sh benches/sequence_cpu.sh BINARY..." >&2; exit 2; }
dir=$(mktemp -d)
echo "| binary | load | blur columns | column fold | zero gap | fold closure | detector | other | total (ms CPU per frame) |"
echo "|---|---|---|---|---|---|---|---|---|"
i=0
for bin in "$@"; do
    i=$((i + 1))
    load=$(cut -d' ' -f1 /proc/loadavg)
    EOIR_BENCH_REPEAT=1 perf record -q -o "$dir/$i.data" -F 4000 "$bin" 1024:64:64 >/dev/null 2>&1
    perf script -i "$dir/$i.data" -F time,ip,sym 2>/dev/null >"$dir/$i.txt"
    python3 - "$dir/$i.txt" "$bin" "$load" <<'PY'
import collections, sys

def part(s):
    if "Segments::column" in s:
        return "blur columns"
    if "fold_column" in s:
        return "column fold"
    if "zero_gap" in s or "Producer::fold_with" in s:
        return "zero gap"
    detector = ("expose_row", "detector::shot", "oisson", "RngExt::sample")
    if any(k in s for k in detector) or s.strip() in ("round", "floor") \
            or "Map<I,F> as core::iter::traits::iterator::Iterator>::fold" in s:
        return "detector"
    if "Fn<A> for &F>::call" in s:
        return "fold closure"
    return "other"

rows = []
for line in open(sys.argv[1]):
    p = line.strip().split(None, 2)
    if p:
        rows.append((float(p[0].rstrip(":")), p[2] if len(p) > 2 else ""))
t0 = next(t for t, s in rows if "Segments::column" in s)
ta = next(t for t, s in rows if t > t0 and "accumulate_block" in s)
t1 = max(t for t, s in rows if t < ta and ("Segments::column" in s or "expose_row" in s))
c = collections.Counter(part(s) for t, s in rows if t0 <= t < t1)
ms = lambda k: c[k] / 4000 / 64 * 1000
parts = ["blur columns", "column fold", "zero gap", "fold closure", "detector", "other"]
cells = " | ".join(f"{ms(k):.2f}" for k in parts)
print(f"| {sys.argv[2]} | {sys.argv[3]} | {cells} | {sum(c.values()) / 4000 / 64 * 1000:.2f} |")
PY
done
rm -rf "$dir"
