#!/usr/bin/env python3
"""Regenerates the pictures of docs/controls.md with the texsyn CLI:

  docs/controls_fields.png     exemplar | field (stripes synthesized along it) | result,
                               for rotate, swirl, radial and perspective fields
  docs/controls_magnify.png    plain 4x upscale of a 4x-synthesized texture vs --magnify 4
  docs/controls_tileable.png   a --tileable-output texture repeated 2x2
  docs/controls_windows.png    four --window tiles synthesized apart, then put together
  docs/controls_features.png   a cell exemplar (drawn here) without --feature-mask, with it and in
                               the paper's mode, the mask resynthesized through each result
                               beside it
  docs/controls_appearance.png --appearance color against the 8D appearance space
  docs/controls_material.png   a height-derived normal map resynthesized with --also along a
                               swirl, lit, against normals recomputed from the result's height

    cargo build --release && python3 docs/make_controls.py

Needs Pillow. Run from the repository root. The field column shows the field itself:
a stripe exemplar (drawn here) synthesized along it without jitter, so orientation and
scale are visible (where the field is not integrable, e.g. swirls, stripes must break).
"""
import os
import random
import subprocess
import tempfile

from PIL import Image, ImageDraw, ImageFilter

BIN = os.environ.get("TEXSYN", "target/release/texsyn")
SIZE, GAP, LABEL = 256, 8, 16
# A 512x512 photograph for the magnification picture (the picture used scikit-image's CC0
# sample `skimage.data.gravel()`); without one that picture is left as it is.
GRAVEL_512 = os.environ.get("GRAVEL_512", "")


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


def cell_exemplar(n, cells=22, seed=7):
    """Tileable cells of flat noisy grey with thin dark borders, and the borders as a mask."""
    rng = random.Random(seed)
    pts = [(rng.uniform(0, n), rng.uniform(0, n)) for _ in range(cells)]
    shade = [rng.randint(95, 165) for _ in pts]
    grain = Image.new("L", (n, n))
    grain.putdata([max(0, min(255, int(rng.gauss(128, 40)))) for _ in range(n * n)])
    grain = grain.filter(ImageFilter.GaussianBlur(0.7))
    img, mask = Image.new("L", (n, n)), Image.new("L", (n, n))
    for y in range(n):
        for x in range(n):
            d = sorted(((x + 0.5 - px - ox) ** 2 + (y + 0.5 - py - oy) ** 2, i)
                       for i, (px, py) in enumerate(pts) for ox in (-n, 0, n) for oy in (-n, 0, n))
            border = d[1][0] ** 0.5 - d[0][0] ** 0.5 < 1.6
            g = grain.getpixel((x, y)) - 128
            v = 55 + 0.3 * g if border else shade[d[0][1]] + 0.5 * g
            img.putpixel((x, y), max(0, min(255, int(v))))
            mask.putpixel((x, y), 255 if border else 0)
    return img, mask


def normals_from_height(grey, strength=3.0):
    """Tangent-space normals (green = y up) of a height given as brightness, wrapping."""
    w, h = grey.size
    px = grey.load()
    out = Image.new("RGB", (w, h))
    for y in range(h):
        for x in range(w):
            dx = (px[(x + 1) % w, y] - px[(x - 1) % w, y]) / 510.0 * strength
            drow = (px[x, (y + 1) % h] - px[x, (y - 1) % h]) / 510.0 * strength
            nx, ny, nz = -dx, drow, 1.0  # y up: the height rises upward when it falls with the row
            l = (nx * nx + ny * ny + nz * nz) ** 0.5
            out.putpixel((x, y), tuple(int(round((c / l + 1) * 127.5)) for c in (nx, ny, nz)))
    return out


def lit(normal_map, light=(-0.5, 0.5, 0.7071)):
    """Lambert shading of a tangent-space normal map (green = y up) lit from the upper left."""
    out = Image.new("L", normal_map.size)
    src = normal_map.convert("RGB").load()
    for y in range(normal_map.height):
        for x in range(normal_map.width):
            n = [c / 127.5 - 1 for c in src[x, y]]
            l = max(1e-6, sum(c * c for c in n) ** 0.5)
            out.putpixel((x, y), int(255 * max(0.0, sum(a * b for a, b in zip(n, light)) / l)))
    return out


def magnify_picture(tmp):
    """128x128 from the 512 px photograph analysed at 128 px: its pixels scaled 4x against
    --magnify 4 (colours from the full photograph)."""
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
    # The photograph is not shipped (set GRAVEL_512): without it the picture stays as it is.
    if GRAVEL_512 and os.path.exists(GRAVEL_512):
        magnify_picture(tmp)
    else:
        print("set GRAVEL_512 to a 512x512 photograph: docs/controls_magnify.png left as it is")

    # Tileable output repeated 2x2.
    t = os.path.join(tmp, "tile.png")
    run("synth", "assets/gravel.png", "-o", t, "--size", "160", "--tileable-output")
    tile = Image.open(t)
    rep = Image.new("L", (320, 320))
    for y in (0, 160):
        for x in (0, 160):
            rep.paste(tile, (x, y))
    labelled([rep], ["--tileable-output 160x160, repeated 2x2"]).save("docs/controls_tileable.png")

    # Infinite windows: four 128x128 windows of one texture, each its own synthesis.
    quads = {}
    for wy in (0, 128):
        for wx in (0, 128):
            q = os.path.join(tmp, f"w{wx}_{wy}.png")
            run("synth", "assets/gravel.png", "-o", q, "--size", "128", "--seed", "5",
                "--window", f"{wx},{wy}")
            quads[(wx, wy)] = Image.open(q)
    apart = Image.new("L", (256 + 3 * GAP, 256 + 3 * GAP), 255)
    together = Image.new("L", (256, 256))
    for (wx, wy), q in quads.items():
        apart.paste(q, (wx + (wx // 128 + 1) * GAP, wy + (wy // 128 + 1) * GAP))
        together.paste(q, (wx, wy))
    labelled([apart, together], ["--window 0,0 / 128,0 / 0,128 / 128,128 (size 128)",
                                 "the same four, put together"]).save("docs/controls_windows.png")

    # Feature mask: an exemplar of cells with thin dark borders, drawn here (so the
    # picture carries no third-party pixels), and the borders as the mask. The mask is
    # also resynthesized through each result (--also) to show where the borders break.
    cells, cmask = cell_exemplar(128)
    cells_path = os.path.join(tmp, "cells.png")
    cmask_path = os.path.join(tmp, "cells_mask.png")
    cells.save(cells_path)
    cmask.save(cmask_path)
    panels = [cells.resize((256, 256), Image.NEAREST), cmask.resize((256, 256), Image.NEAREST)]
    labels = ["exemplar (128 px, shown 2x)", "its feature mask"]
    for extra, label in [([], "no mask"),
                         (["--feature-mask", cmask_path], "--feature-mask (mode both)"),
                         (["--feature-mask", cmask_path, "--feature-mode", "appearance"],
                          "--feature-mode appearance")]:
        r_out = os.path.join(tmp, "cells_out.png")
        m_out = os.path.join(tmp, "cells_out_mask.png")
        run("synth", cells_path, "-o", r_out, "--size", str(SIZE), "--seed", "1", "--tileable",
            "--also", f"plain:{cmask_path}={m_out}", *extra)
        panels += [Image.open(r_out), Image.open(m_out)]
        labels += [label, f"{label}: mask carried along"]
    stack([labelled(panels[i:i + 2], labels[i:i + 2])
           for i in range(0, len(panels), 2)]).save("docs/controls_features.png")

    # Appearance space against plain colour (the paper's Figure 4).
    rows = []
    for ex in ["assets/brick.png", "assets/grass.png"]:
        imgs = [Image.open(ex)]
        for space in ["color", "neighborhood"]:
            a_out = os.path.join(tmp, f"app_{space}.png")
            run("synth", ex, "-o", a_out, "--size", str(SIZE), "--seed", "1",
                "--appearance", space)
            imgs.append(Image.open(a_out))
        rows.append(labelled(imgs, ["exemplar", "--appearance color",
                                    "--appearance neighborhood (default)"]))
    stack(rows).save("docs/controls_appearance.png")

    # Material set: a normal map derived from the brick's brightness (mortar raised),
    # resynthesized along a swirl; its x, y turn with the texture. Lit from the upper
    # left, it should shade like normals recomputed from the resynthesized brightness.
    brick = Image.open("assets/brick.png").convert("L")
    nmap = normals_from_height(brick)
    nmap_path = os.path.join(tmp, "brick_normal.png")
    nmap.save(nmap_path)
    c_out = os.path.join(tmp, "mat.png")
    n_out = os.path.join(tmp, "mat_normal.png")
    p_out = os.path.join(tmp, "mat_plain.png")
    run("synth", "assets/brick.png", "-o", c_out, "--size", str(SIZE), "--seed", "1",
        "--field", "swirl", "--also", f"normal:{nmap_path}={n_out}",
        "--also", f"plain:{nmap_path}={p_out}")
    colour = Image.open(c_out).convert("L")
    labelled([brick, nmap, Image.open(c_out), Image.open(n_out)],
             ["exemplar", "normals (height)", "result, --field swirl",
              "--also normal:... (turned)"]).save(os.path.join(tmp, "m1.png"))
    labelled([lit(Image.open(n_out)), lit(Image.open(p_out)), lit(normals_from_height(colour))],
             ["lit: resynthesized normals", "lit: same, not turned (plain:)",
              "lit: normals from the result's brightness"]).save(os.path.join(tmp, "m2.png"))
    stack([Image.open(os.path.join(tmp, "m1.png")), Image.open(os.path.join(tmp, "m2.png"))]
          ).save("docs/controls_material.png")
print("wrote docs/controls_{fields,magnify,tileable,windows,features,appearance,material}.png")
