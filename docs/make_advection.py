#!/usr/bin/env python3
"""Regenerates docs/advection_vortex.png (docs/advection.md): frames 0, 100, 200 and 300 of
the default vortex advecting the bundled gravel and brick, 256x256, with the texsyn CLI's
default options (in 2D `--keep-look --fade 2`).

    cargo build --release && python3 docs/make_advection.py

Needs Pillow. Run from the repository root. Takes about a minute on lavapipe.
"""
import os
import subprocess
import tempfile

from PIL import Image, ImageDraw

EXEMPLARS = ["gravel", "brick"]
FRAMES = [0, 100, 200, 300]
SIZE, GAP, LABEL = 256, 8, 14
BIN = os.environ.get("TEXSYN", "target/release/texsyn")

rows = []
with tempfile.TemporaryDirectory() as tmp:
    for name in EXEMPLARS:
        folder = os.path.join(tmp, name)
        subprocess.run([BIN, "-q", "advect", f"assets/{name}.png", "--flow", "vortex",
                        "--frames", str(FRAMES[-1]), "--size", str(SIZE), "-o", folder],
                       check=True)
        rows.append((name, [Image.open(os.path.join(folder, f"frame_{f:05}.png")).convert("L")
                            for f in FRAMES]))

width = len(FRAMES) * SIZE + (len(FRAMES) - 1) * GAP
height = len(rows) * (LABEL + SIZE) + (len(rows) - 1) * GAP
canvas = Image.new("L", (width, height), 255)
draw = ImageDraw.Draw(canvas)
y = 0
for name, frames in rows:
    for i, (f, img) in enumerate(zip(FRAMES, frames)):
        x = i * (SIZE + GAP)
        draw.text((x, y), f"{name}, frame {f}", fill=0)
        canvas.paste(img, (x, y + LABEL))
    y += LABEL + SIZE + GAP
canvas.save("docs/advection_vortex.png", optimize=True)
print("wrote docs/advection_vortex.png")
