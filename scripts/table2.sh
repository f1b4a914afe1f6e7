#!/usr/bin/env bash
# Regenerates every Table II block of the READMEs from the noise_sweep example's output.
#
# A block is the Markdown between a marker line and `<!-- /table2 -->`:
#
#   <!-- table2 profile=cf21-brushless seed=2025 trials=500 -->
#   | noise | estimator | ... |
#   <!-- /table2 -->
#
# For each marker, this runs
#   cargo run --release --example noise_sweep -- --profile P --seed S --trials N --markdown --quiet
# and puts its output between the two lines. A marker ending in ` curve=gain` runs
#   ... --gain-curve instead of --markdown
# (success over the integral gain). Every column is a function of the seeds only (any CPU,
# any thread count), so a block reproduces exactly.
#
#   scripts/table2.sh            rewrite every block
#   scripts/table2.sh --check    exit 1 if any block differs from what the code prints
#   scripts/table2.sh --max-trials 20 [--check]   only the blocks of at most 20 trials
#   scripts/table2.sh --only cf21 [--check]       only the blocks of one profile
#
# CI checks the small block (tests/table2.rs, in-process); this script also covers the
# 500-trial tables, which take minutes.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

check=0
max_trials=0
only=
while (($#)); do
  case "$1" in
    --check) check=1 ;;
    --max-trials) max_trials="$2"; shift ;;
    --only) only="$2"; shift ;;
    *) echo "usage: $0 [--check] [--max-trials N] [--only PROFILE]" >&2; exit 2 ;;
  esac
  shift
done

files=(README.md tagk-sim/README.md)
cargo build --release --quiet --example noise_sweep
bin=target/release/examples/noise_sweep
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
status=0
for f in "${files[@]}"; do
  [ -f "$f" ] || continue
  out="$tmp/$(basename "$f").new"
  : > "$out"
  skipping=0
  while IFS= read -r line || [ -n "$line" ]; do
    if [[ "$line" =~ ^\<!--\ table2\ profile=([a-z0-9-]+)\ seed=([0-9]+)\ trials=([0-9]+)(\ curve=gain)?\ --\>$ ]]; then
      printf '%s\n' "$line" >> "$out"
      profile=${BASH_REMATCH[1]} seed=${BASH_REMATCH[2]} trials=${BASH_REMATCH[3]}
      mode=--markdown
      [[ -n "${BASH_REMATCH[4]}" ]] && mode=--gain-curve
      if ((max_trials > 0 && trials > max_trials)) || [[ -n "$only" && "$profile" != "$only" ]]; then
        continue
      fi
      echo "$f: table2 profile=$profile seed=$seed trials=$trials $mode" >&2
      "$bin" --profile "$profile" --seed "$seed" --trials "$trials" "$mode" --quiet \
        --out "$tmp/out" >> "$out"
      skipping=1
      continue
    fi
    if ((skipping)); then
      if [[ "$line" == "<!-- /table2 -->" ]]; then
        skipping=0
        printf '%s\n' "$line" >> "$out"
      fi
      continue
    fi
    printf '%s\n' "$line" >> "$out"
  done < "$f"
  if ((check)); then
    if ! diff -u "$f" "$out"; then
      echo "$f: a Table II block differs from what the code prints" >&2
      status=1
    fi
  else
    cp "$out" "$f"
  fi
done
exit $status
