#!/usr/bin/env bash
# Flash and RAM of the C-only example device (examples/c) as Cortex-M firmware:
# a minimal fd device (-DCO_CONFIG_CLASSIC=0) and a full classic device
# (-DCO_CONFIG_FD=0), each for Cortex-M4 and Cortex-M0+ (arm-none-eabi-gcc -Os,
# newlib-nano, --gc-sections, NDEBUG; the whole firmware incl. crt0 and the
# board file). flash = text + data, RAM = data + bss (static; no heap is used).
#
#   bash bench/footprint.sh          (needs gcc-arm-none-eabi, libnewlib-arm-none-eabi)
set -euo pipefail
cd "$(dirname "$0")/.."
command -v arm-none-eabi-gcc >/dev/null || { echo "arm-none-eabi-gcc not installed"; exit 1; }
make -s -C examples/c cross >/dev/null
printf '%-26s %8s %6s %7s %8s %8s\n' firmware text data bss flash RAM
for elf in build/examples/cortex-m4_fd.elf build/examples/cortex-m4_classic.elf \
           build/examples/cortex-m0plus_fd.elf build/examples/cortex-m0plus_classic.elf; do
    arm-none-eabi-size "$elf" | awk -v name="$(basename "$elf" .elf)" 'NR == 2 {
        printf "%-26s %8d %6d %7d %8d %8d\n", name, $1, $2, $3, $1 + $2, $2 + $3 }'
done
echo
echo "largest RAM objects (cortex-m4_fd):"
arm-none-eabi-nm -S --size-sort -C build/examples/cortex-m4_fd.elf | awk '$3 ~ /^[bBdD]$/' |
    tail -3 | while read -r _addr size _kind name; do printf '  %6d  %s\n' "$((16#$size))" "$name"; done
