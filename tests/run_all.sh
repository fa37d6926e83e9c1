#!/usr/bin/env bash
# The whole test suite, from a fresh Debian machine with Python and gcc:
#   1. installs what it needs (Debian packages when root, a venv with the package + test deps),
#   2. C unit tests, plain and under AddressSanitizer + UndefinedBehaviorSanitizer (plus the
#      core's clang check, Cortex-M cross build and the Windows compile check with mingw),
#      and the runtime driven from threads under ThreadSanitizer and LeakSanitizer,
#      then the core's libFuzzer harnesses for a bounded time each (tests/fuzz),
#   3. pytest over the in-process bus and python-can's virtual bus, the atheris fuzz harnesses
#      of the OD file importers (~20 s each), then pytest's mem:/python-can subset again under
#      the portable loop (what Windows and macOS run),
#   4. the vcan lane (real kernel SocketCAN, CAN FD): directly where this kernel has vcan,
#      otherwise inside a small qemu VM booted with a stock Debian kernel (tests/vm/).
# Exits non-zero when any stage fails; the last line sums up every test run.
set -u
cd "$(dirname "$0")/.."
ROOT=$PWD
VENV=${CANOPENFD_VENV:-$ROOT/.venv}
RESULTS=$ROOT/build/test-results
VCAN_IFACES="vcan0:72 vcan1:72 vcan2:16"
mkdir -p "$RESULTS"
rm -f "$RESULTS"/*.xml "$RESULTS"/*.txt

say() { printf '\n=== %s ===\n' "$*"; }

# ---------------------------------------------------------------- 1. setup
# gcc-arm-none-eabi + libnewlib-arm-none-eabi: the core's Cortex-M cross build (tests/c);
# gcc-mingw-w64-x86-64: the Windows compile check of the extension's sources (tests/c);
# libclang-rt-14-dev: clang's libFuzzer and sanitizer runtimes (tests/fuzz);
# mosquitto: the real MQTT broker the MQTT gateway tests run on loopback.
debian_packages=(libcmocka-dev clang python3-dev python3-venv iproute2
                 gcc-arm-none-eabi libnewlib-arm-none-eabi gcc-mingw-w64-x86-64
                 libclang-rt-14-dev mosquitto)
have_vcan=0
if bash tests/vm/have_vcan.sh; then have_vcan=1; else
    debian_packages+=(qemu-system-x86 linux-image-amd64 busybox-static)
fi
missing=()
for p in "${debian_packages[@]}"; do
    dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        say "installing Debian packages: ${missing[*]}"
        export DEBIAN_FRONTEND=noninteractive
        apt-get update -q >/dev/null && apt-get install -y -q "${missing[@]}" >/dev/null \
            || { echo "apt-get install ${missing[*]} failed"; exit 1; }
    else
        echo "missing Debian packages (install them as root): ${missing[*]}"
    fi
fi

say "python environment ($VENV)"
[ -x "$VENV/bin/python" ] || python3 -m venv "$VENV" || { echo "python3 -m venv failed"; exit 1; }
"$VENV/bin/python" -m pip install -q --upgrade pip >/dev/null
# setuptools copies build/lib into the wheel: modules moved or removed since an
# earlier build would be installed again from there.
rm -rf build/lib build/lib.* build/bdist.*
"$VENV/bin/python" -m pip install -q ".[test]" || { echo "pip install .[test] failed"; exit 1; }

status=0

# ---------------------------------------------------------------- 2. C tests
say "C unit tests (plain, then ASan+UBSan; clang check, Cortex-M cross build)"
make -C tests/c 2>&1 | tee "$RESULTS/c-tests.txt"
[ "${PIPESTATUS[0]}" = 0 ] || status=1
# The runtime (core + Linux port, the extension's sources) driven from threads while it is
# stopped under them: ThreadSanitizer, then ASan+LeakSanitizer+UBSan (tests/stress/).
say "runtime under threads (ThreadSanitizer, then ASan+LSan+UBSan)"
make -s -C tests/stress run 2>&1 | tee "$RESULTS/stress.txt"
[ "${PIPESTATUS[0]}" = 0 ] || status=1

# The core's decoders and state machines under libFuzzer (ASan+UBSan), FUZZ_SECONDS
# (15) each over the seed corpora, after replaying every saved regression input.
say "C fuzz harnesses (libFuzzer + ASan/UBSan, ${FUZZ_SECONDS:-15} s each)"
make -C tests/fuzz ci 2>&1 | tee "$RESULTS/fuzz.txt"
[ "${PIPESTATUS[0]}" = 0 ] || status=1

# The C-only example device; built here because the vcan lane runs it and
# the VM sees the tree read-only (tests/test_c_example.py checks it).
make -s -C examples/c linux || status=1

# ---------------------------------------------------------------- 3. pytest
# The venv's pytest (not `python -m pytest`) so the installed package is
# tested, not the source tree's canopenfd/ without its compiled core.
say "pytest: in-process bus, python-can virtual bus, CLI"
"$VENV/bin/pytest" -p no:cacheprovider -m "not vcan" --junitxml="$RESULTS/pytest-local.xml" tests || status=1

# The atheris harnesses of tests/fuzz/py (README-py.md): the object-dictionary file importers
# (EDS/DCF, XDD/XDC, import_od + the C definition tables) on mutated bytes, each for a bounded
# time from the test files as seeds; an escaping exception fails the harness and leaves the
# input in $RESULTS/pyfuzz/. atheris is in the test extra where it has wheels (Linux x86_64,
# CPython <= 3.13); elsewhere it needs clang with libFuzzer, so the stage is skipped.
pyfuzz_harnesses=(fuzz_eds fuzz_xdd fuzz_import_od)
pyfuzz_seconds=${CANOPENFD_PYFUZZ_SECONDS:-20}
say "pyfuzz: atheris harnesses of the OD file importers (${pyfuzz_seconds} s each)"
if "$VENV/bin/python" -c "import atheris" 2>/dev/null; then
    mkdir -p "$RESULTS/pyfuzz"
    pyfuzz_passed=0 pyfuzz_failed=0
    for h in "${pyfuzz_harnesses[@]}"; do
        log=$RESULTS/pyfuzz/$h.log
        if "$VENV/bin/python" "tests/fuzz/py/$h.py" -max_total_time="$pyfuzz_seconds" -timeout=10 \
                -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$RESULTS/pyfuzz/$h-" \
                >"$log" 2>&1; then
            pyfuzz_passed=$((pyfuzz_passed + 1))
            echo "$h: passed, $(grep -o 'Done [0-9]* runs in [0-9]* second' "$log" | tail -1)"
        else
            pyfuzz_failed=$((pyfuzz_failed + 1))
            echo "$h: FAILED (log: $log, input: $RESULTS/pyfuzz/$h-*)"
            grep -v '^INFO: Instrumenting' "$log" | tail -40
        fi
    done
    echo "pyfuzz: $pyfuzz_passed passed, $pyfuzz_failed failed" | tee "$RESULTS/pyfuzz.txt"
    [ "$pyfuzz_failed" = 0 ] || status=1
else
    echo "pyfuzz: 0 passed, 0 failed, ${#pyfuzz_harnesses[@]} skipped (atheris is not installed:" \
         "no wheel for this platform/Python; it builds only with clang and libFuzzer)" \
        | tee "$RESULTS/pyfuzz.txt"
fi

# The loop Windows and macOS run (a condition variable until the next deadline instead of
# epoll), on Linux: the tests of mem: and python-can lines that exercise the real loop
# (NMT/heartbeat timing, USDO/SDO transfers, PDOs, SYNC/TIME/EMCY, waits, shutdown).
say "pytest: mem:/python-can subset under the portable loop (CANOPENFD_PORTABLE_LOOP=1)"
portable_subset=(tests/test_membus.py tests/test_hostbus.py tests/test_services.py
                 tests/test_service_stats.py tests/test_usdo_client.py tests/test_usdo_server.py
                 tests/test_sdo_client.py tests/test_pdo_config.py tests/test_indications.py
                 tests/test_local_od.py tests/test_app_store.py tests/test_portable_loop.py)
CANOPENFD_PORTABLE_LOOP=1 "$VENV/bin/pytest" -p no:cacheprovider -m "not vcan" \
    --junitxml="$RESULTS/pytest-portable-loop.xml" "${portable_subset[@]}" || status=1

# ---------------------------------------------------------------- 4. vcan lane
run_vcan() {
    env CANOPENFD_VCAN=vcan0,vcan1,vcan2 "$@" "$VENV/bin/pytest" -p no:cacheprovider -m vcan \
        --junitxml="$RESULTS/pytest-vcan.xml" tests
}
if [ $have_vcan = 1 ]; then
    say "pytest: vcan lane on this kernel"
    bash tests/vm/setup_vcan.sh --ifaces "$VCAN_IFACES" && run_vcan || status=1
else
    say "pytest: vcan lane inside a qemu VM (this kernel has no vcan)"
    # Writes inside the VM do not reach the host, so its pytest summary line is
    # read from the streamed output. Python runs ~20x slower there: protocol
    # timeouts in the tests are scaled by CANOPENFD_TIME_SCALE.
    bash tests/vm/run_in_vm.sh --ifaces "$VCAN_IFACES" -- \
        env CANOPENFD_TIME_SCALE=${CANOPENFD_TIME_SCALE:-10} CANOPENFD_VCAN=vcan0,vcan1,vcan2 \
        "$VENV/bin/pytest" -p no:cacheprovider -m vcan -rs tests 2>&1 | tee "$RESULTS/pytest-vm.txt"
    [ "${PIPESTATUS[0]}" = 0 ] || status=1
fi

# ---------------------------------------------------------------- summary
say "summary"
"$VENV/bin/python" - "$RESULTS" <<'PY'
import glob, os, re, sys, xml.etree.ElementTree as ET
passed = failed = skipped = 0
text = open(sys.argv[1] + "/c-tests.txt").read()
m = re.findall(r"c-tests[^:\n]*: (\d+) passed, (\d+) failed", text)
if m:
    passed += int(m[-1][0]); failed += int(m[-1][1])
# Other stages end their output with "<stage>: N passed, M failed" (the last one counts).
for path in sorted(glob.glob(sys.argv[1] + "/*.txt")):
    if path.endswith(("/c-tests.txt", "/pytest-vm.txt")):
        continue
    m = re.findall(r"^\w+: (\d+) passed, (\d+) failed(?:, (\d+) skipped)?", open(path).read(),
                   re.M)
    if m:
        passed += int(m[-1][0]); failed += int(m[-1][1]); skipped += int(m[-1][2] or 0)
    else:
        failed += 1   # the stage printed no summary at all
vm = glob.glob(sys.argv[1] + "/pytest-vm.txt")
if vm:
    # pytest's closing line, e.g. "==== 12 passed, 1 failed, 2 skipped in 80s ===="
    lines = [l for l in open(vm[0]) if re.search(r"=+ .*\d+ (passed|failed|error)", l)]
    if lines:
        counts = dict((k, int(n)) for n, k in re.findall(r"(\d+) (passed|failed|errors?|skipped)", lines[-1]))
        passed += counts.get("passed", 0); skipped += counts.get("skipped", 0)
        failed += counts.get("failed", 0) + counts.get("error", 0) + counts.get("errors", 0)
    else:
        failed += 1   # the VM lane produced no pytest summary at all
for path in glob.glob(sys.argv[1] + "/pytest-*.xml"):
    for suite in ET.parse(path).getroot().iter("testsuite"):
        n, f, e, s = (int(suite.get(k, 0)) for k in ("tests", "failures", "errors", "skipped"))
        passed += n - f - e - s; failed += f + e; skipped += s
print(f"all: {passed} passed, {failed} failed, {skipped} skipped")
PY
exit $status
