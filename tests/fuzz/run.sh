#!/usr/bin/env bash
# Runs the built harnesses (called by the Makefile):
#   run.sh ci      BUILD SECONDS harness...   regressions, then SECONDS of fuzzing each
#   run.sh long    BUILD SECONDS harness...   campaign, corpus kept in BUILD/corpus/
#   run.sh regress BUILD 0       harness...   every regress/<harness>/ input once
# One line per harness; the last line is "fuzz: N passed, M failed" (ci, regress).
set -u
cd "$(dirname "$0")"
mode=$1 build=$2 seconds=$3
shift 3
passed=0 failed=0
# The CAN line inputs are short records; 2 KB is hundreds of them. An input's
# cost spans 1000x (a fast periodic timer fires through every time record and
# settle): the entropic scheduler weighs inputs by their run time, so the few
# slow ones do not eat most of the campaign (2.6-3.7x executions in 45 s for
# stack and services, coverage equal or higher).
opts=(-max_len=2048 -timeout=10 -rss_limit_mb=2048 -print_final_stats=1
      -entropic_scale_per_exec_time=1)

# Replays regress/<h>/*: true when every one passes (none is fine).
regress() {
    local h=$1 bin=$build/bin/fuzz_$1 files=() f
    for f in regress/"$h"/*; do [ -f "$f" ] && files+=("$f"); done
    [ ${#files[@]} = 0 ] && { REG_N=0; return 0; }
    REG_N=${#files[@]}
    "$bin" "${opts[@]}" "${files[@]}" >"$build/log/$h-regress.txt" 2>&1
}

# Fuzzes harness h for `seconds` over work corpus dir w (seeded from corpus/<h>).
fuzz() {
    local h=$1 w=$2 bin=$build/bin/fuzz_$1 log=$build/log/$1-$mode.txt
    mkdir -p "$w" "$build/artifacts"
    "$bin" "${opts[@]}" -max_total_time="$seconds" -artifact_prefix="$build/artifacts/$h-" \
        "$w" "corpus/$h" >"$log" 2>&1
    local rc=$?
    local execs cov ft
    execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
    cov=$(grep -oE 'cov: [0-9]+ ft: [0-9]+' "$log" | tail -n 1)
    corp=$(ls "$w" | wc -l)
    if [ $rc = 0 ]; then
        echo "fuzz $h: ok, ${execs:-?} executions in ${seconds} s, ${cov:-cov: ?}, corpus $corp"
    else
        echo "fuzz $h: FAILED (exit $rc), ${execs:-?} executions, ${cov:-cov: ?}; log $log:"
        grep -E 'ERROR|invariant|runtime error|Test unit written|SUMMARY' "$log" | head -n 8 | sed 's/^/    /'
    fi
    return $rc
}

mkdir -p "$build/log"
for h in "$@"; do
    ok=1
    case $mode in
    regress|ci)
        if regress "$h"; then
            [ "$mode" = regress ] && echo "fuzz $h: $REG_N regression inputs pass"
        else
            ok=0
            echo "fuzz $h: a regression input FAILED; log $build/log/$h-regress.txt:"
            grep -E 'ERROR|invariant|runtime error|Running:|SUMMARY' "$build/log/$h-regress.txt" \
                | head -n 8 | sed 's/^/    /'
        fi
        if [ "$mode" = ci ] && [ $ok = 1 ]; then
            rm -rf "$build/ci/$h"
            fuzz "$h" "$build/ci/$h" || ok=0
        fi
        ;;
    long)
        fuzz "$h" "$build/corpus/$h" || ok=0
        ;;
    esac
    if [ $ok = 1 ]; then passed=$((passed + 1)); else failed=$((failed + 1)); fi
done
echo "fuzz: $passed passed, $failed failed"
[ $failed = 0 ]
