#!/bin/sh
# Peak RSS (GNU time's "Maximum resident set size") of `eoir run` for a MultimIR sequence
# at several frame counts, for one or two builds; BENCHMARKS.md round 22.
#
#   sh benches/stream_memory.sh [FRAMES...]          (default: 8 64 256)
#
# EOIR_BENCH_BINS: space-separated `eoir` binaries to compare (default:
# target/release/eoir). With two, the product files of each frame count are compared
# byte for byte (report.json and report.html hold timings and are skipped).
# The scene (384 × 288 MultimIR plus a 40-pixel margin, 4 samples per pixel, ~400 MB) is
# written once to $EOIR_BENCH_DIR (default /tmp/eoir-bench-stream). The camera drifts at
# 0.5 m/s at 1900 m, 50 frames/s, so every frame differs and stays inside the scene.
set -eu
bins=${EOIR_BENCH_BINS:-target/release/eoir}
dir=${EOIR_BENCH_DIR:-/tmp/eoir-bench-stream}
[ $# -gt 0 ] || set -- 8 64 256
mkdir -p "$dir"
first=$(echo "$bins" | cut -d' ' -f1)
[ -f "$dir/scene.hdr" ] || "$first" scene thermal --sensor multimir --option sequence=aircraft \
    --margin-px 40 -o "$dir/scene.hdr" >/dev/null 2>&1
echo "| frames | binary | peak RSS (KiB) | wall |"
echo "|---|---|---|---|"
for n in "$@"; do
    i=0
    for bin in $bins; do
        i=$((i + 1))
        out="$dir/out$i"
        rm -rf "$out"
        /usr/bin/time -v "$bin" run --sensor multimir --option sequence=still \
            --set clock.frame_rate_hz=50 --set motion.velocity_m_s=0.5 \
            "$dir/scene.hdr" -o "$out" --frames "$n" --quiet --seed 5 \
            2>"$dir/time.txt" >/dev/null
        rss=$(grep "Maximum resident" "$dir/time.txt" | awk '{print $NF}')
        wall=$(grep "Elapsed (wall" "$dir/time.txt" | awk '{print $NF}')
        echo "| $n | $bin | $rss | $wall |"
    done
    if [ "$i" -eq 2 ]; then
        for f in $(ls "$dir/out1"); do
            case $f in
                report.json | report.html) ;;
                *) cmp -s "$dir/out1/$f" "$dir/out2/$f" || echo "products differ: $n frames, $f" ;;
            esac
        done
    fi
done
