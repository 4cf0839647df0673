#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Log-log plot of the main-road matrix (scripts/bench main-road): time vs resolution.

    scripts/plot_main_road.py CSV PNG

CSV is the matrix written by scripts/bench (columns kind, mesh, group, resolution, band,
lf_status, lf_s, vt_status, vt_s, ...). One line per method per mesh group, band 3:
levelforge (solid) and vdb_tool (dashed) for armadillo Loop x2, armadillo_100k and the median of
the shared watertight set (at resolutions where every watertight mesh ran). Rows that timed out,
failed or were skipped are left out of the lines.

No plotting library: the PNG is drawn on an RGB canvas with a small built-in 5x7 bitmap font and
written with zlib + struct.
"""
import csv
import math
import statistics
import struct
import sys
import zlib

# 5x7 glyphs, one 5-bit row per entry, most significant bit on the left.
FONT = {
    " ": [0, 0, 0, 0, 0, 0, 0],
    "0": [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E],
    "1": [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E],
    "2": [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F],
    "3": [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E],
    "4": [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02],
    "5": [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E],
    "6": [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E],
    "7": [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
    "8": [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E],
    "9": [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C],
    "A": [0x0E, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
    "B": [0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E],
    "C": [0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E],
    "D": [0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C],
    "E": [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F],
    "F": [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10],
    "G": [0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F],
    "H": [0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
    "I": [0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E],
    "J": [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C],
    "K": [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11],
    "L": [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F],
    "M": [0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11],
    "N": [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11],
    "O": [0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
    "P": [0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10],
    "Q": [0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D],
    "R": [0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11],
    "S": [0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E],
    "T": [0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04],
    "U": [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
    "V": [0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04],
    "W": [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A],
    "X": [0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11],
    "Y": [0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04],
    "Z": [0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F],
    ".": [0, 0, 0, 0, 0, 0x0C, 0x0C],
    ",": [0, 0, 0, 0, 0x0C, 0x04, 0x08],
    "-": [0, 0, 0, 0x1F, 0, 0, 0],
    "_": [0, 0, 0, 0, 0, 0, 0x1F],
    "/": [0x01, 0x01, 0x02, 0x04, 0x08, 0x10, 0x10],
    "(": [0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02],
    ")": [0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08],
    ":": [0, 0x0C, 0x0C, 0, 0x0C, 0x0C, 0],
    "=": [0, 0, 0x1F, 0, 0x1F, 0, 0],
    "+": [0, 0x04, 0x04, 0x1F, 0x04, 0x04, 0],
    ">": [0x08, 0x04, 0x02, 0x01, 0x02, 0x04, 0x08],
    "<": [0x02, 0x04, 0x08, 0x10, 0x08, 0x04, 0x02],
    "%": [0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03],
    "*": [0, 0x04, 0x15, 0x0E, 0x15, 0x04, 0],
    "?": [0x0E, 0x11, 0x01, 0x02, 0x04, 0, 0x04],
}


class Canvas:
    def __init__(self, w, h, bg=(255, 255, 255)):
        self.w, self.h = w, h
        self.px = bytearray(bytes(bg) * (w * h))

    def set(self, x, y, c):
        if 0 <= x < self.w and 0 <= y < self.h:
            i = 3 * (y * self.w + x)
            self.px[i:i + 3] = bytes(c)

    def rect(self, x0, y0, x1, y1, c):
        for y in range(max(0, y0), min(self.h, y1 + 1)):
            for x in range(max(0, x0), min(self.w, x1 + 1)):
                self.set(x, y, c)

    def line(self, x0, y0, x1, y1, c, width=1, dash=None):
        """Line by sampling along its length; dash = (on, off) in pixels."""
        n = int(max(abs(x1 - x0), abs(y1 - y0))) + 1
        r = width // 2
        for i in range(n + 1):
            if dash and (i % (dash[0] + dash[1])) >= dash[0]:
                continue
            t = i / n
            x = int(round(x0 + (x1 - x0) * t))
            y = int(round(y0 + (y1 - y0) * t))
            for dy in range(-r, width - r):
                for dx in range(-r, width - r):
                    self.set(x + dx, y + dy, c)

    def text(self, x, y, s, c=(0, 0, 0), scale=2):
        """Text with its top-left corner at (x, y); lower case is drawn as upper case."""
        for ch in s.upper():
            g = FONT.get(ch, FONT["?"])
            for row, bits in enumerate(g):
                for col in range(5):
                    if bits & (0x10 >> col):
                        self.rect(x + col * scale, y + row * scale,
                                  x + col * scale + scale - 1, y + row * scale + scale - 1, c)
            x += 6 * scale

    @staticmethod
    def text_width(s, scale=2):
        return 6 * scale * len(s) - scale

    def text_vertical(self, x, y, s, c=(0, 0, 0), scale=2):
        """Text rotated 90 degrees counter-clockwise, its baseline start at (x, y) going up."""
        for ch in s.upper():
            g = FONT.get(ch, FONT["?"])
            for row, bits in enumerate(g):
                for col in range(5):
                    if bits & (0x10 >> col):
                        px, py = x + row * scale, y - col * scale
                        self.rect(px, py - scale + 1, px + scale - 1, py, c)
            y -= 6 * scale

    def write_png(self, path):
        raw = b"".join(b"\x00" + bytes(self.px[3 * y * self.w:3 * (y + 1) * self.w])
                       for y in range(self.h))

        def chunk(kind, data):
            body = kind + data
            return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

        png = b"\x89PNG\r\n\x1a\n"
        png += chunk(b"IHDR", struct.pack(">IIBBBBB", self.w, self.h, 8, 2, 0, 0, 0))
        png += chunk(b"IDAT", zlib.compress(raw, 9))
        png += chunk(b"IEND", b"")
        with open(path, "wb") as f:
            f.write(png)


def number(s):
    try:
        v = float(s)
        return v if math.isfinite(v) and v > 0 else None
    except (TypeError, ValueError):
        return None


def series_from_csv(path):
    with open(path, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r.get("kind") == "mesh" and r.get("band") == "3"]
    out = []  # (label, colour, dashed, [(res, seconds)])

    def pick(name, prog):
        pts = []
        for r in rows:
            if r["mesh"] != name or r[prog + "_status"] != "ok":
                continue
            res, s = number(r["resolution"]), number(r[prog + "_s"])
            if res and s:
                pts.append((res, s))
        return sorted(pts)

    wt = sorted({r["mesh"] for r in rows if r["group"] == "watertight"})

    def median(prog):
        pts = []
        for res in sorted({number(r["resolution"]) for r in rows if r["group"] == "watertight"} - {None}):
            ts = [number(r[prog + "_s"]) for r in rows
                  if r["group"] == "watertight" and number(r["resolution"]) == res
                  and r[prog + "_status"] == "ok"]
            ts = [t for t in ts if t]
            if wt and len(ts) == len(wt):
                pts.append((res, statistics.median(ts)))
        return pts

    groups = [("armadillo loop x2", (200, 40, 40), lambda p: pick("armadillo_loop2", p)),
              ("armadillo_100k", (40, 90, 200), lambda p: pick("armadillo_100k", p)),
              ("watertight median (%d)" % len(wt), (30, 150, 60), median)]
    for label, colour, get in groups:
        for prog, name, dashed in (("lf", "levelforge", False), ("vt", "vdb_tool", True)):
            pts = get(prog)
            if pts:
                out.append(("%s %s" % (name, label), colour, dashed, pts))
    return out


def plot(series, path, title):
    W, H = 1000, 700
    L, R, T, B = 110, 30, 60, 90
    c = Canvas(W, H)
    pts = [p for s in series for p in s[3]]
    if pts:
        xmin, xmax = min(p[0] for p in pts), max(p[0] for p in pts)
        ymin, ymax = min(p[1] for p in pts), max(p[1] for p in pts)
    else:
        xmin, xmax, ymin, ymax = 64, 2048, 0.1, 100
    lx0, lx1 = math.floor(math.log2(xmin) - 0.3), math.ceil(math.log2(xmax) + 0.3)
    if lx1 == lx0:
        lx1 += 1
    ly0, ly1 = math.floor(math.log10(ymin)), math.ceil(math.log10(ymax))
    if ly1 == ly0:
        ly1 += 1

    def X(v):
        return L + (math.log2(v) - lx0) / (lx1 - lx0) * (W - L - R)

    def Y(v):
        return H - B - (math.log10(v) - ly0) / (ly1 - ly0) * (H - T - B)

    grid, axis = (225, 225, 225), (0, 0, 0)
    for e in range(lx0, lx1 + 1):
        x = int(X(2 ** e))
        c.line(x, T, x, H - B, grid)
        lab = str(2 ** e)
        c.text(x - Canvas.text_width(lab) // 2, H - B + 10, lab)
    for e in range(ly0, ly1 + 1):
        y = int(Y(10 ** e))
        c.line(L, y, W - R, y, grid)
        for m in range(2, 10):
            if e < ly1:
                ym = int(Y(m * 10 ** e))
                c.line(L - 4, ym, L, ym, axis)
        lab = ("%g" % (10 ** e))
        c.text(L - 10 - Canvas.text_width(lab), y - 7, lab)
        c.line(L - 8, y, L, y, axis)
    c.line(L, T, L, H - B, axis, 2)
    c.line(L, H - B, W - R, H - B, axis, 2)
    xl = "voxels along the longest side of the mesh box (log2)"
    c.text((L + W - R) // 2 - Canvas.text_width(xl) // 2, H - B + 40, xl)
    c.text_vertical(20, (T + H - B) // 2 + Canvas.text_width("wall seconds (log10)") // 2, "wall seconds (log10)")
    c.text(L, 20, title)
    for label, colour, dashed, p in series:
        for (x0, y0), (x1, y1) in zip(p, p[1:]):
            c.line(X(x0), Y(y0), X(x1), Y(y1), colour, 3, (10, 7) if dashed else None)
        for x, y in p:
            c.rect(int(X(x)) - 3, int(Y(y)) - 3, int(X(x)) + 3, int(Y(y)) + 3, colour)
    # legend, bottom right inside the plot (times grow with the resolution: that corner is free)
    wmax = max([Canvas.text_width(s[0]) for s in series] + [0])
    lx, ly = W - R - 15 - (60 + wmax + 8), H - B - 12 - 22 * len(series)
    if series:
        c.rect(lx - 8, ly - 8, lx + 60 + wmax + 8, ly + 22 * len(series), (255, 255, 255))
        c.line(lx - 8, ly - 8, lx + 60 + wmax + 8, ly - 8, axis)
        c.line(lx - 8, ly + 22 * len(series), lx + 60 + wmax + 8, ly + 22 * len(series), axis)
        c.line(lx - 8, ly - 8, lx - 8, ly + 22 * len(series), axis)
        c.line(lx + 60 + wmax + 8, ly - 8, lx + 60 + wmax + 8, ly + 22 * len(series), axis)
    for i, (label, colour, dashed, _) in enumerate(series):
        y = ly + 22 * i + 6
        c.line(lx, y, lx + 48, y, colour, 3, (10, 7) if dashed else None)
        c.text(lx + 60, y - 6, label)
    if not series:
        c.text(L + 40, T + 40, "no completed band-3 rows in the csv")
    c.write_png(path)


def main(argv):
    if len(argv) != 3:
        sys.stderr.write(__doc__)
        return 2
    series = series_from_csv(argv[1])
    plot(series, argv[2], "levelforge mesh-to-sdf vs vdb_tool -mesh2ls, whole process, band 3")
    print("plot_main_road: wrote %s (%d lines)" % (argv[2], len(series)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
