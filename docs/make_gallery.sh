#!/usr/bin/env bash
# Regenerate the pictures of docs/gallery.md from the shipped cases:
#   bash docs/make_gallery.sh            (under a minute on 2 cores)
# Runs room, room-obstacles and two-exits into $WORK (default /tmp/femcrowd-gallery),
# draws them with `femcrowd plot`, and copies the pictures shown in the gallery to
# docs/gallery/ under stable names: <case>_<field>_<time>s.png, <case>_curves.png,
# <case>_density.gif.
set -euo pipefail
cd "$(dirname "$0")/.."
WORK=${WORK:-/tmp/femcrowd-gallery}
FEMCROWD=${FEMCROWD:-femcrowd}
mkdir -p "$WORK" docs/gallery
rm -f docs/gallery/*

gallery() {  # NAME "PLOT OPTIONS" ITEM...; ITEM = FIELD@TIME (the picture nearest TIME s) | curves | animation
    local name=$1 options=$2 plots="$WORK/$1-plots" item field t
    shift 2
    "$FEMCROWD" run "cases/$name" --out "$WORK/$name" -q
    # shellcheck disable=SC2086  # the options are words
    "$FEMCROWD" plot "$WORK/$name" -o "$plots" -q $options
    for item in "$@"; do
        case $item in
            curves) cp "$plots/curves.png" "docs/gallery/${name}_curves.png" ;;
            animation) cp "$plots/density.gif" "docs/gallery/${name}_density.gif" ;;
            *@*)
                field=${item%@*} t=${item#*@}
                cp "$plots/${field}_t$(printf %04d "$t")"*.png "docs/gallery/${name}_${field}_${t}s.png" ;;
        esac
    done
}

gallery room "--times 0,4,8,12 --no-animation" density@0 density@4 density@8 density@12 pressure@8 curves
gallery room-obstacles "--times 8" density@8 pressure@8 animation
gallery two-exits "--times 12 --no-animation" density@12 pressure@12 curves
ls -l docs/gallery
