#!/usr/bin/env bash
# Regenerate the pictures of docs/gallery.md from the shipped cases:
#   bash docs/make_gallery.sh            (about 2 minutes on 2 cores)
# Runs room, room-obstacles and two-exits into $WORK (default /tmp/femcrowd-gallery),
# draws them with `femcrowd plot`, and copies the pictures shown in the gallery
# to docs/gallery/ as <case>_<picture>.
set -euo pipefail
cd "$(dirname "$0")/.."
WORK=${WORK:-/tmp/femcrowd-gallery}
FEMCROWD=${FEMCROWD:-femcrowd}
mkdir -p "$WORK" docs/gallery

gallery() {  # case, plot options, pictures to keep
    local case=$1 options=$2
    shift 2
    "$FEMCROWD" run "cases/$case" --out "$WORK/$case" -q
    # shellcheck disable=SC2086  # options are words
    "$FEMCROWD" plot "$WORK/$case" -o "$WORK/$case-plots" -q $options
    for picture in "$@"; do
        cp "$WORK/$case-plots/$picture" "docs/gallery/${case}_$picture"
    done
}

gallery room "--times 0,4,8,12 --no-animation" \
    density_t0000.0.png density_t0004.0.png density_t0008.0.png density_t0012.0.png \
    pressure_t0008.0.png curves.png
gallery room-obstacles "--times 4,8" \
    density_t0008.0.png pressure_t0008.0.png density.gif
gallery two-exits "--times 6,12 --no-animation" \
    density_t0012.png pressure_t0012.png curves.png
ls -l docs/gallery
