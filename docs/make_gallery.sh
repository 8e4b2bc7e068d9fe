#!/usr/bin/env bash
# Regenerate the pictures of docs/gallery.md from the shipped cases:
#   bash docs/make_gallery.sh            (under a minute on 2 cores)
#   bash docs/make_gallery.sh extensions (the populations and the bottleneck, about 2 minutes)
# Runs room, room-obstacles and two-exits (or the cases of the extensions) into $WORK (default
# results/gallery), draws them with `femcrowd plot`, and copies the pictures shown in the gallery to
# $PICTURES under stable names: <case>_<field>_<time>s.png, <case>_curves.png, <case>_density.gif.
# $PICTURES defaults to results/gallery/pictures, outside the tracked tree; to replace the pictures of
# the gallery: PICTURES=docs/gallery bash docs/make_gallery.sh
set -euo pipefail
cd "$(dirname "$0")/.."
WORK=${WORK:-results/gallery}
PICTURES=${PICTURES:-results/gallery/pictures}
FEMCROWD=${FEMCROWD:-femcrowd}
SET=${1:-basic}
mkdir -p "$WORK" "$PICTURES"

gallery() {  # NAME "PLOT OPTIONS" ITEM...; ITEM = FIELD@TIME (the picture nearest TIME s) | curves | animation
    local name=$1 options=$2 plots="$WORK/$1-plots" item field t
    shift 2
    rm -f "$PICTURES/${name}"_*
    # shellcheck disable=SC2086  # the run options are words
    "$FEMCROWD" run "cases/$name" --out "$WORK/$name" -q ${RUN:-}
    # shellcheck disable=SC2086  # the options are words
    "$FEMCROWD" plot "$WORK/$name" -o "$plots" -q $options
    for item in "$@"; do
        case $item in
            curves) cp "$plots/curves.png" "$PICTURES/${name}_curves.png" ;;
            animation) cp "$plots/density.gif" "$PICTURES/${name}_density.gif" ;;
            *@*)
                field=${item%@*} t=${item#*@}
                cp "$plots/${field}_t$(printf %04d "$t")"*.png "$PICTURES/${name}_${field}_${t}s.png" ;;
        esac
    done
}

if [ "$SET" = basic ]; then
    gallery room "--times 0,4,8,12 --no-animation" density@0 density@4 density@8 density@12 pressure@8 curves
    gallery room-obstacles "--times 8" density@8 pressure@8 animation
    gallery two-exits "--times 12 --no-animation" density@12 pressure@12 curves
else  # docs/extensions.md: each population in its own colour map; the micro runs shortened
    gallery counterflow "--times 4,8,12 --no-animation" populations@4 populations@8 populations@12 pressure@8
    gallery two-groups "--times 4,10 --no-animation" populations@4 populations@10 curves
    gallery bottleneck "--times 30 --no-animation" density@30 curves
    RUN="--set time.end=24" gallery counterflow-micro "--times 8,16 --no-animation" populations@8 populations@16
    RUN="--set time.end=20" gallery two-groups-micro "--times 20 --no-animation" populations@20
    RUN="--set time.end=20" gallery bottleneck-micro "--times 10 --no-animation" discs@10
fi
ls -l "$PICTURES"
