#!/bin/bash
# Instructions per frame / segment of the core under valgrind's callgrind
# (bench/frame_cost.c says what each figure runs). Needs valgrind.
#   bash bench/frame_cost.sh BINARY [OUTDIR]
# For each figure: (Ir of the long run - Ir of the short run) / (units difference).
set -euo pipefail
bin=${1:?usage: frame_cost.sh BINARY [OUTDIR]}
out=${2:-$(dirname "$bin")/callgrind}
command -v valgrind >/dev/null || { echo "frame_cost.sh: valgrind not found (apt-get install valgrind)" >&2; exit 2; }
rm -rf "$out"
mkdir -p "$out"
valgrind --tool=callgrind --collect-atstart=no --callgrind-out-file="$out/callgrind.out" \
    "$bin" >"$out/stdout" 2>"$out/valgrind.log" || { cat "$out/valgrind.log" >&2; exit 1; }
# One dump per measured run: "desc: Trigger: Client Request: <figure> <units>", "totals: <Ir>".
for f in $(ls "$out"/callgrind.out.* | sort -V); do
    desc=$(sed -n 's/^desc: Trigger: Client Request: //p' "$f")
    total=$(sed -n 's/^totals: //p' "$f")
    if [ -n "$desc" ]; then echo "$desc ${total:-0}"; fi
done | awk '
    { name = $1; units = $2; ir = $3
      if (!(name in n1)) { order[++k] = name; n1[name] = units; i1[name] = ir }
      else { n2[name] = units; i2[name] = ir } }
    END {
      printf "%-10s %10s %14s %10s %14s %12s\n", "figure", "units", "Ir", "units", "Ir", "Ir/unit"
      for (j = 1; j <= k; j++) { f = order[j]
        if (!(f in n2)) { print "frame_cost.sh: " f ": one run only" > "/dev/stderr"; exit 1 }
        if (n2[f] < n1[f]) { t = n1[f]; n1[f] = n2[f]; n2[f] = t; t = i1[f]; i1[f] = i2[f]; i2[f] = t }
        printf "%-10s %10d %14d %10d %14d %12.1f\n", f, n1[f], i1[f], n2[f], i2[f],
               (i2[f] - i1[f]) / (n2[f] - n1[f]) }
    }'
