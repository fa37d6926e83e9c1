#!/bin/sh
# Run the built test binaries of the given variants and print a total line.
# Usage: run.sh BUILD_DIR VARIANT...   (called by the Makefile)
# Exit status: 0 when every test passed and no binary crashed.
build=$1
shift
passed=0
failed=0
crashed=0
for variant in "$@"; do
    for bin in "$build/$variant"/test_*; do
        [ -x "$bin" ] || continue
        name="$variant/$(basename "$bin")"
        echo "=== $name"
        out=$("$bin" 2>&1)
        rc=$?
        printf '%s\n' "$out"
        # a binary may run several groups: every group's summary counts
        p=$(printf '%s\n' "$out" | sed -n 's/^\[  PASSED  \] \([0-9]*\) test.*/\1/p' |
            awk '{ n += $1 } END { if (NR) print n }')
        f=$(printf '%s\n' "$out" | sed -n 's/^\[  FAILED  \] \([0-9]*\) test.*/\1/p' |
            awk '{ n += $1 } END { if (NR) print n }')
        passed=$((passed + ${p:-0}))
        failed=$((failed + ${f:-0}))
        if [ "$rc" -ne 0 ] && [ -z "$f" ]; then
            echo "!!! $name exited with status $rc without a cmocka summary (crash or sanitizer abort)"
            crashed=$((crashed + 1))
        fi
    done
done
echo "c-tests ($*): $passed passed, $failed failed, $crashed binaries crashed"
[ "$failed" -eq 0 ] && [ "$crashed" -eq 0 ]
