#!/usr/bin/env python3
"""Times and scores texsyn against Embark's `texture-synthesis` CLI on the same machine.

For each exemplar: `texsyn analyze` once, then in alternating rounds the whole `texsyn synth`
process from the image and from the analysis file (wall clock), and `--ts-runs` (default 1)
`texture-synthesis` runs (its defaults; its outputs vary from run to run). Quality comes from
`texsyn eval` on both outputs (the largest verbatim copy from texsyn's coordinate map, written
in a separate, untimed run). Prints a Markdown table and the medians of the ratios, the
figures docs/quality.md reports, with the coarse energies both on the grid and any-phase.

    cargo build --release
    cargo install --locked texture-synthesis-cli --version 0.8.3 --root /tmp/tscli
    python3 tools/compare.py --ts /tmp/tscli/bin/texture-synthesis assets/*.png

Only the standard library is used. Figures swing with the machine's load: run it on a quiet
machine, and compare only runs made side by side.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time


def run(cmd):
    """Runs cmd, returns its wall time in seconds; exits on failure with its stderr."""
    t0 = time.perf_counter()
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    dt = time.perf_counter() - t0
    if r.returncode != 0:
        sys.exit(f"failed ({r.returncode}): {' '.join(cmd)}\n{r.stderr}")
    return dt, r.stdout


def evaluate(texsyn, exemplar, image, coords=None):
    cmd = [texsyn, "eval", exemplar, image]
    if coords:
        cmd += ["--coords", coords]
    _, out = run(cmd)
    return json.loads(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("exemplars", nargs="+")
    ap.add_argument("--texsyn", default="target/release/texsyn")
    ap.add_argument("--ts", default="texture-synthesis", help="texture-synthesis CLI")
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--rounds", type=int, default=3, help="texsyn runs per setting")
    ap.add_argument("--ts-runs", type=int, default=1,
                    help="texture-synthesis runs per exemplar (its outputs vary from run to "
                         "run): its time is their median, its quality figures their mean")
    ap.add_argument("--extra", default="", help="extra texsyn synth options, space-separated")
    args = ap.parse_args()
    extra = args.extra.split()
    size = str(args.size)
    work = tempfile.mkdtemp(prefix="texsyn-compare-")
    rows = []
    for ex in args.exemplars:
        name = os.path.splitext(os.path.basename(ex))[0]
        tsa = os.path.join(work, name + ".tsa")
        out_img = os.path.join(work, name + "_img.png")
        out_file = os.path.join(work, name + "_file.png")
        coords = os.path.join(work, name + ".exr")
        out_ts = os.path.join(work, name + "_ts.png")
        print(f"{name}: analysis, texsyn x{args.rounds} x 2, texture-synthesis x{args.ts_runs}",
              file=sys.stderr)
        run([args.texsyn, "analyze", "-q", ex, "-o", tsa])
        synth = [args.texsyn, "synth", "-q", "--size", size, "--seed", str(args.seed)] + extra
        t_img, t_file = [], []
        for _ in range(args.rounds):
            t_img.append(run(synth[:2] + [ex, "-o", out_img] + synth[2:])[0])
            t_file.append(run(synth[:2] + [tsa, "-o", out_file] + synth[2:])[0])
        t_ts, qts = [], []
        for _ in range(max(1, args.ts_runs)):
            t_ts.append(run([args.ts, "--out-size", size, "--seed", str(args.seed), "-o",
                             out_ts, "generate", ex])[0])
            qts.append(evaluate(args.texsyn, ex, out_ts))
        t_ts = statistics.median(t_ts)
        qt = {
            section: {k: statistics.mean(r[section][k] for r in qts) for k in keys}
            for section, keys in (("texture_energy", ("full", "half", "quarter")),
                                  ("texture_energy_any_phase", ("half", "quarter")),
                                  ("histogram_emd", ("mean",)))
        }
        run(synth[:2] + [tsa, "-o", out_file, "--coords-out", coords] + synth[2:])
        q = evaluate(args.texsyn, ex, out_file, coords)
        rows.append({
            "name": name,
            "ts": t_ts,
            "img": statistics.median(t_img),
            "file": statistics.median(t_file),
            "energy": [q["texture_energy"][k] / qt["texture_energy"][k]
                       for k in ("full", "half", "quarter")],
            "energy_any": [q["texture_energy_any_phase"][k] / qt["texture_energy_any_phase"][k]
                           for k in ("half", "quarter")],
            "hist": q["histogram_emd"]["mean"] / qt["histogram_emd"]["mean"],
            "copy": q["verbatim"]["largest_region_fraction"],
        })
    print(f"| exemplar | texture-synthesis | texsyn from the image | from a file "
          f"| speed-up (image / file) | energy ratio full / half / quarter "
          f"| any-phase half / quarter | histogram distance ratio | largest verbatim copy |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        e = " / ".join(f"{v:.3f}" for v in r["energy"])
        a = " / ".join(f"{v:.3f}" for v in r["energy_any"])
        print(f"| {r['name']} | {r['ts']:.2f} s | {r['img']:.3f} s | {r['file']:.3f} s "
              f"| {r['ts'] / r['img']:.1f}x / {r['ts'] / r['file']:.1f}x | {e} | {a} "
              f"| {r['hist']:.3f} | {r['copy']:.3f} |")
    med = statistics.median
    print()
    print(f"medians over {len(rows)}: speed-up {med([r['ts'] / r['img'] for r in rows]):.1f}x "
          f"(whole process) / {med([r['ts'] / r['file'] for r in rows]):.1f}x (from a file); "
          f"energy " + " / ".join(f"{med([r['energy'][i] for r in rows]):.3f}" for i in range(3))
          + "; any-phase " + " / ".join(f"{med([r['energy_any'][i] for r in rows]):.3f}"
                                        for i in range(2))
          + f"; histogram {med([r['hist'] for r in rows]):.3f}x; "
          f"largest copy at most {max(r['copy'] for r in rows):.3f}")


if __name__ == "__main__":
    main()
