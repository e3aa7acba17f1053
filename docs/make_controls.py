#!/usr/bin/env python3
"""Regenerates the pictures of README's "Controls" section with the texsyn CLI:

  docs/controls_fields.png     exemplar | field (stripes synthesized along it) | result,
                               for rotate, swirl, radial and perspective fields
  docs/controls_magnify.png    plain 4x upscale of a 4x-synthesized texture vs --magnify 4
  docs/controls_tileable.png   a --tileable-output texture repeated 2x2

    cargo build --release && python3 docs/make_controls.py

Needs Pillow. Run from the repository root. The field column shows the field itself:
a stripe exemplar (drawn here) synthesized along it without jitter, so orientation and
scale are visible (where the field is not integrable, e.g. swirls, stripes must break).
"""
import os
import subprocess
import tempfile

from PIL import Image, ImageDraw

BIN = os.environ.get("TEXSYN", "target/release/texsyn")
SIZE, GAP, LABEL = 256, 8, 16
GRAVEL_512 = os.environ.get("GRAVEL_512", "../shared/exemplars/cc0_gravel.png")


def run(*args):
    subprocess.run([BIN, "-q", *args], check=True)


def labelled(images, labels):
    w = sum(i.width for i in images) + GAP * (len(images) - 1)
    h = max(i.height for i in images) + LABEL
    out = Image.new("RGB", (w, h), "white")
    d = ImageDraw.Draw(out)
    x = 0
    for img, text in zip(images, labels):
        out.paste(img.convert("RGB"), (x, LABEL))
        d.text((x + 2, 2), text, fill="black")
        x += img.width + GAP
    return out


def stack(rows):
    w = max(r.width for r in rows)
    h = sum(r.height for r in rows) + GAP * (len(rows) - 1)
    out = Image.new("RGB", (w, h), "white")
    y = 0
    for r in rows:
        out.paste(r, (0, y))
        y += r.height + GAP
    return out


with tempfile.TemporaryDirectory() as tmp:
    # A tileable stripe exemplar: bright bands along x every 8 px, with a thin dark
    # tick every 16 px along each band so that the x direction is visible too. No
    # jitter: the stripes then show the field itself rather than a rearrangement.
    stripes = Image.new("L", (32, 32), 60)
    d = ImageDraw.Draw(stripes)
    for y in range(0, 32, 8):
        d.rectangle([0, y, 31, y + 2], fill=220)
        for x in range(0, 32, 16):
            d.rectangle([x, y, x + 1, y + 2], fill=30)
    stripes_path = os.path.join(tmp, "stripes.png")
    stripes.save(stripes_path)

    rows = []
    for field, label in [("rotate:30", "rotate:30"), ("swirl", "swirl"),
                         ("radial", "radial"), ("perspective", "perspective")]:
        f_out = os.path.join(tmp, "field.png")
        r_out = os.path.join(tmp, "result.png")
        run("synth", stripes_path, "-o", f_out, "--size", str(SIZE), "--field", field,
            "--tileable", "--seed", "3", "--randomness", "0")
        run("synth", "assets/brick.png", "-o", r_out, "--size", str(SIZE), "--field", field,
            "--seed", "1")
        rows.append(labelled(
            [Image.open("assets/brick.png"), Image.open(f_out), Image.open(r_out)],
            ["exemplar", f"field: --field {label}", "result"]))
    stack(rows).save("docs/controls_fields.png")

    # Magnification: synthesize 128x128 from the 512 px photograph analysed at 128 px;
    # left: its pixels scaled 4x; right: --magnify 4 (colours from the full photograph).
    small = os.path.join(tmp, "small.png")
    full = Image.open(GRAVEL_512).convert("L")
    full.resize((128, 128), Image.BOX).save(small)
    plain = os.path.join(tmp, "plain.png")
    mag = os.path.join(tmp, "mag.png")
    run("synth", small, "-o", plain, "--size", "96", "--seed", "2")
    run("synth", GRAVEL_512, "-o", mag, "--size", "96", "--seed", "2", "--magnify", "4")
    labelled([Image.open(plain).resize((384, 384), Image.NEAREST), Image.open(mag)],
             ["96x96 synthesized, shown 4x (nearest)", "--magnify 4 (384x384)"]
             ).save("docs/controls_magnify.png")

    # Tileable output repeated 2x2.
    t = os.path.join(tmp, "tile.png")
    run("synth", "assets/gravel.png", "-o", t, "--size", "160", "--tileable-output")
    tile = Image.open(t)
    rep = Image.new("L", (320, 320))
    for y in (0, 160):
        for x in (0, 160):
            rep.paste(tile, (x, y))
    labelled([rep], ["--tileable-output 160x160, repeated 2x2"]).save("docs/controls_tileable.png")
print("wrote docs/controls_fields.png, docs/controls_magnify.png, docs/controls_tileable.png")
