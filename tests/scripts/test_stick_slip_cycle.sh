#!/usr/bin/env bash
# seed000_train's 8th trial (mu 1.13, grip 2.5 N), labels only: some large-deformation steps
# cycle near their fixed point while nodes flip between stick and slip; with held contact sets
# (mechanics/hyperelastic_contact.cpp) no frame is flagged. Usage: EXE ROOT.
set -euo pipefail
exe=$1
root=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
sed -e 's/integrator: fast/integrator: preview/' -e 's/images: true/images: false/' \
    "$root/datasets_spec/seed000_train.yaml" > "$tmp/spec.yaml"
grep -q 'images: false' "$tmp/spec.yaml"
"$exe" generate "$tmp/spec.yaml" -o "$tmp/out" --max-trials 8 --shard 8/8 -q \
    --cache-dir "$tmp/cache" > "$tmp/log" 2>&1 || { cat "$tmp/log"; exit 1; }
cat "$tmp/log"
record="$tmp/out/_progress/trial_000007.json"
cat "$record"
grep -Eq '"frames": [0-9]{3}' "$record"
grep -q '"flagged_frames": 0,' "$record"
if grep -q flagged "$tmp/log"; then exit 1; fi
