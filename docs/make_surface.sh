#!/usr/bin/env bash
# Regenerates docs/surface_bunny.png and docs/surface_torus.png (docs/surfaces.md).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --example surface
tmp=$(mktemp -d)
./target/release/texsyn surface assets/meshes/bunny.glb assets/brick.png -o "$tmp/bunny.glb" \
    --render docs/surface_bunny.png --views 3 --view-size 320 --seed 1
./target/release/examples/surface "$tmp"
cp "$tmp/torus.png" docs/surface_torus.png
rm -rf "$tmp"
