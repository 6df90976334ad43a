#!/usr/bin/env python3
"""Renders one scene with every lightfarm method as concurrent jobs on a farm and writes a
contact sheet: each image labelled with its method, its render time and its error against the
brute-force job over the same virtual lights. A pipeline script in a few lines of the client.

    python3 contact_sheet.py SCENE --server HOST:PORT [--token-file F] [--out sheet.png]
                             [--lights N] [--resolution WxH] [--methods a,b,...]

Writes the sheet (PNG) and a Markdown table beside it (same name, .md).
"""

import argparse
import concurrent.futures
import os
import sys

import numpy as np

import lightfarm

METHODS = ["brute", "mrcs", "lightcuts", "lightslice", "sparse-completion", "adaptive-completion", "path", "auto"]


def rel_l1(reference, image):
    """rel_l1 = |ref - img|_1 / |ref|_1 over all pixel channels (as `lightfarm compare`)."""
    ref, img = reference[..., :3].astype(np.float64), image[..., :3].astype(np.float64)
    return float(np.abs(ref - img).sum() / max(np.abs(ref).sum(), 1e-30))


def to_srgb8(image):
    linear = np.clip(np.nan_to_num(image[..., :3], nan=0.0, posinf=1.0), 0.0, 1.0)
    srgb = np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * np.power(linear, 1 / 2.4) - 0.055)
    return (srgb * 255 + 0.5).astype(np.uint8)


def write_sheet(path, tiles, columns=4, min_tile=192, label_height=50):
    """tiles: [(label lines, HxWx3 float image)] -> one PNG, a grid with a label under each.
    Small images are enlarged (pixel replication) so that each label fits under its tile."""
    import OpenImageIO as oiio
    h0, w0 = tiles[0][1].shape[:2]
    scale = max(1, -(-min_tile // w0))
    h, w = h0 * scale, w0 * scale
    rows = (len(tiles) + columns - 1) // columns
    sheet = np.full((rows * (h + label_height), columns * w, 3), 24, np.uint8)
    for i, (_, image) in enumerate(tiles):
        r, c = divmod(i, columns)
        big = np.repeat(np.repeat(to_srgb8(image), scale, axis=0), scale, axis=1)
        sheet[r * (h + label_height):r * (h + label_height) + h, c * w:(c + 1) * w] = big
    buf = oiio.ImageBuf(oiio.ImageSpec(sheet.shape[1], sheet.shape[0], 3, "uint8"))
    buf.set_pixels(oiio.ROI(), sheet)
    for i, (lines, _) in enumerate(tiles):
        r, c = divmod(i, columns)
        for k, line in enumerate(lines):
            # render_text needs a font (Debian: fonts-dejavu-core); the Markdown table has it all anyway.
            oiio.ImageBufAlgo.render_text(buf, c * w + 6, r * (h + label_height) + h + 15 + 15 * k, line,
                                          12, "DejaVuSans", [0.9, 0.9, 0.9])
    if not buf.write(path):
        raise RuntimeError("cannot write " + path + ": " + buf.geterror())


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene")
    parser.add_argument("--server", required=True)
    parser.add_argument("--token-file")
    parser.add_argument("--out", default="contact-sheet.png")
    parser.add_argument("--lights", type=int, default=10000)
    parser.add_argument("--resolution", default="256x256")
    parser.add_argument("--methods", default=",".join(METHODS))
    parser.add_argument("--timeout", type=float, default=3600)
    args = parser.parse_args(argv)

    token = open(args.token_file).read().strip() if args.token_file else None
    width, height = (int(v) for v in args.resolution.lower().split("x"))
    methods = [m for m in args.methods.split(",") if m]
    if "brute" not in methods:
        methods.insert(0, "brute")  # the errors are against it

    with lightfarm.Client(args.server, token=token) as client:
        # Every method at once: the farm schedules them; the scene's blobs upload once.
        jobs = {m: client.submit(args.scene, method=m, lights=args.lights, resolution=(width, height),
                                 name="contact sheet: " + m) for m in methods}
        print("submitted", ", ".join("{0} (job {1})".format(m, j.id) for m, j in jobs.items()))

        def finish(method):
            job = jobs[method]
            try:
                job.wait(timeout=args.timeout)
                return method, job.result(), None
            except lightfarm.LightfarmError as e:
                return method, None, e.message

        with concurrent.futures.ThreadPoolExecutor(len(methods)) as pool:
            results = {m: (r, err) for m, r, err in pool.map(finish, methods)}

    brute, brute_err = results["brute"]
    if brute is None:
        sys.exit("the brute-force job failed: " + brute_err)
    tiles, table = [], ["| method | time (s) | rel_l1 vs brute | job |", "|---|---:|---:|---|"]
    for m in methods:
        result, err = results[m]
        if result is None:
            table.append("| {0} | | | failed: {1} |".format(m, err))
            continue
        seconds = result.stats["time"]["total_s"]
        error = rel_l1(brute.image, result.image)
        chosen = result.stats.get("method", m)
        name = m if chosen == m else "{0} ({1})".format(m, chosen)
        tiles.append(([name, "{0:.2f} s".format(seconds), "rel_l1 {0:.4f} vs brute".format(error)], result.image))
        table.append("| {0} | {1:.2f} | {2:.4f} | {3} |".format(name, seconds, error, jobs[m].id))
    write_sheet(args.out, tiles)
    md = os.path.splitext(args.out)[0] + ".md"
    with open(md, "w") as f:
        f.write("# {0}: {1} lights, {2}x{3}\n\n".format(args.scene, args.lights, width, height))
        f.write("\n".join(table) + "\n")
    print("\n".join(table))
    print("wrote", args.out, "and", md)


if __name__ == "__main__":
    main()
