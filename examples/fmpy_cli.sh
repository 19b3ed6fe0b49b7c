#!/usr/bin/env bash
# The FMU from a shell: build it, read its interface with `fmpy info`, run it with `fmpy simulate`
# (start values, output file), and judge the result with `bouncingball check`.
# Needs: pip install -e '.[fmu]' in the checkout (pythonfmu and FMPy; the build also needs a C compiler).
# Usage: bash fmpy_cli.sh [OUTPUT_DIR]      (default: the current directory)
set -euo pipefail
out="${1:-.}"
mkdir -p "$out"
fmu="$out/BouncingBall.fmu"

# 1. Build the FMU; its reference result, BouncingBall_ref.csv, is written beside it.
bouncingball build-fmu -o "$fmu"

# 2. Its variables, units, default experiment and capabilities.
fmpy info "$fmu"

# 3. The ball on the Moon, dropped from 1 m: start values are NAME VALUE pairs.
fmpy simulate "$fmu" --stop-time 6 --output-interval 0.01 \
    --start-values g 1.62 h 1.0 --output-file "$out/moon.csv"

# 4. Judge it against the exact solution, given the same start values (exit 1 if it is off).
bouncingball check "$out/moon.csv" --start-value g=1.62 --start-value h=1.0 --tolerance 1e-6

# 5. The reference the FMU carries passes the same check (default experiment: article, 8 s, 1 ms).
bouncingball check "${fmu%.fmu}_ref.csv"
