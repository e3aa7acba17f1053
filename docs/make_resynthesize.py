#!/usr/bin/env python3
"""Regenerates docs/advection_resynthesize.png (docs/advection.md): frame 300 of the default
vortex, 256x256, with the levels below the finest advected (`--carry`, the paper's scheme),
with `--keep-look --fade 0` (the advected levels below the coarsest one remade wherever the
flow turns them, the coarsest renewed where it has turned by about 5 degrees), with
`--keep-look --fade 1` (pops shown blended for a frame) and with `--keep-look --fade 2`
(blended over two frames; the default in 2D), for the
bundled brick and gravel; next to each, where frame 300 differs from
frame 299 moved by the flow (white: a change of 1/3 of full scale or more), which is the
popping `--keep-look` costs and `--fade` spreads over frames.

    cargo build --release && python3 docs/make_resynthesize.py

Needs Pillow and NumPy. Run from the repository root. Takes about two minutes on lavapipe.
"""
import os
import subprocess
import tempfile

import numpy as np
from PIL import Image, ImageDraw

EXEMPLARS = ["brick", "gravel"]
CONFIGS = [("--carry", ["--carry"]), ("--keep-look --fade 0", ["--keep-look", "--fade", "0"]),
           ("--keep-look --fade 1", ["--keep-look", "--fade", "1"]),
           ("--fade 2 (default)", ["--keep-look", "--fade", "2"])]
SIZE, GAP, LABEL, OMEGA = 256, 8, 14, 0.01
BIN = os.environ.get("TEXSYN", "target/release/texsyn")


def warped(a):
    """Frame `a` moved one frame along the default vortex (rigid rotation about the centre),
    sampled bilinearly: the flow-warped previous frame."""
    c = SIZE / 2
    ys, xs = np.mgrid[0:SIZE, 0:SIZE].astype(np.float32) + 0.5
    sx = xs + OMEGA * (ys - c) - 0.5
    sy = ys - OMEGA * (xs - c) - 0.5
    x0 = np.clip(np.floor(sx).astype(int), 0, SIZE - 2)
    y0 = np.clip(np.floor(sy).astype(int), 0, SIZE - 2)
    tx, ty = sx - x0, sy - y0
    return (a[y0, x0] * (1 - tx) * (1 - ty) + a[y0, x0 + 1] * tx * (1 - ty)
            + a[y0 + 1, x0] * (1 - tx) * ty + a[y0 + 1, x0 + 1] * tx * ty)


tiles = []
with tempfile.TemporaryDirectory() as tmp:
    for name in EXEMPLARS:
        for label, args in CONFIGS:
            folder = os.path.join(tmp, f"{name}{len(tiles)}")
            subprocess.run([BIN, "-q", "advect", f"assets/{name}.png", "--flow", "vortex",
                            "--frames", "300", "--size", str(SIZE), "-o", folder] + args,
                           check=True)
            load = lambda f: np.asarray(Image.open(os.path.join(folder, f"frame_{f:05}.png"))
                                        .convert("L"), dtype=np.float32)
            last = load(300)
            change = np.clip(np.abs(warped(load(299)) - last) * 3, 0, 255).astype(np.uint8)
            tiles.append((f"{name}, {label}, frame 300", Image.fromarray(last.astype(np.uint8))))
            tiles.append((f"change from frame 299", Image.fromarray(change)))

cols = 2 * len(CONFIGS)
rows = (len(tiles) + cols - 1) // cols
width = cols * SIZE + (cols - 1) * GAP
height = rows * (LABEL + SIZE) + (rows - 1) * GAP
canvas = Image.new("L", (width, height), 255)
draw = ImageDraw.Draw(canvas)
for i, (text, img) in enumerate(tiles):
    x, y = (i % cols) * (SIZE + GAP), (i // cols) * (LABEL + SIZE + GAP)
    draw.text((x, y), text, fill=0)
    canvas.paste(img, (x, y + LABEL))
out = "docs/advection_resynthesize.png"
tmp_out = out + ".partial.png"
canvas.save(tmp_out, optimize=True)
os.replace(tmp_out, out)
print(out)
