#!/usr/bin/env python3
"""Regenerates docs/exemplar_and_result.png: bundled exemplars (left, actual size) next
to textures synthesized from them (right), with the texsyn CLI.

    cargo build --release && python3 docs/make_picture.py

Needs Pillow. Run from the repository root.
"""
import os
import subprocess
import tempfile

from PIL import Image, ImageDraw

EXEMPLARS = ["gravel", "brick"]
OUT_W, OUT_H, SEED = 384, 256, 1
GAP, LABEL = 8, 14
BIN = os.environ.get("TEXSYN", "target/release/texsyn")

rows = []
with tempfile.TemporaryDirectory() as tmp:
    for name in EXEMPLARS:
        src = f"assets/{name}.png"
        out = os.path.join(tmp, f"{name}.png")
        subprocess.run([BIN, "-q", "synth", src, "-o", out, "--size", f"{OUT_W}x{OUT_H}",
                        "--seed", str(SEED)], check=True)
        rows.append((name, Image.open(src).convert("L"), Image.open(out).convert("L")))

ex_w = max(e.width for _, e, _ in rows)
width = ex_w + GAP + OUT_W
height = len(rows) * (LABEL + OUT_H) + (len(rows) - 1) * GAP
canvas = Image.new("L", (width, height), 255)
draw = ImageDraw.Draw(canvas)
y = 0
for name, ex, out in rows:
    draw.text((0, y), f"{name}.png {ex.width}x{ex.height}", fill=0)
    draw.text((ex_w + GAP, y), f"synthesized {OUT_W}x{OUT_H}, seed {SEED}", fill=0)
    canvas.paste(ex, (0, y + LABEL))
    canvas.paste(out, (ex_w + GAP, y + LABEL))
    y += LABEL + OUT_H + GAP
canvas.save("docs/exemplar_and_result.png", optimize=True)
print(f"wrote docs/exemplar_and_result.png ({width}x{height})")
