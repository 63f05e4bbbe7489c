#!/usr/bin/env bash
# The instruction-set check (generators/cli/cpu_check.cpp) on emulated CPUs: an x86-64-v3
# build refuses to start on one without AVX2 (Nehalem), naming the CPU level and the portable
# rebuild, and starts on one with it (Haswell). Usage: test_cpu_check.sh QEMU CHROMASIM
set -uo pipefail
qemu=$1 exe=$2
fail() { echo "FAIL: $*" >&2; exit 1; }

out=$("$qemu" -cpu Nehalem "$exe" --version 2>&1 | grep -v '^qemu-x86_64: warning')
rc=${PIPESTATUS[0]}
[ "$rc" -eq 1 ] || fail "Nehalem: exit status $rc, want 1 (output: $out)"
grep -q "this build is for x86-64-v3 CPUs" <<<"$out" || fail "Nehalem: no message naming x86-64-v3: $out"
grep -q -- "-DCHROMASIM_ARCH=portable" <<<"$out" || fail "Nehalem: the message names no fix: $out"
grep -q "^chromasim [0-9]" <<<"$out" && fail "Nehalem: the program ran on: $out"

out=$("$qemu" -cpu Haswell "$exe" --version 2>&1 | grep -v '^qemu-x86_64: warning')
rc=${PIPESTATUS[0]}
[ "$rc" -eq 0 ] || fail "Haswell: exit status $rc, want 0 (output: $out)"
grep -q "^chromasim [0-9.]* (instruction set x86-64-v3)" <<<"$out" || fail "Haswell: $out"
echo "ok: refused on Nehalem, ran on Haswell"
