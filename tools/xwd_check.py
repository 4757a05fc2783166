#!/usr/bin/env python3
"""Checks an X11 screenshot (xwd -root) is not blank and converts it to PNG (stdlib only).

usage: xwd_check.py SHOT.xwd OUT.png
Exits 1 when the image has fewer than 64 distinct colours (an empty or failed window).
"""
import struct
import sys
import zlib


def read_xwd(path):
    data = open(path, "rb").read()
    h = struct.unpack(">25I", data[:100])
    header_size, width, height = h[0], h[4], h[5]
    byte_order, bpp, bytes_per_line, ncolors = h[7], h[11], h[12], h[19]
    if bpp != 32:
        sys.exit(f"{path}: {bpp} bits per pixel; expected 32")
    start = header_size + 12 * ncolors
    rows = []
    for y in range(height):
        line = data[start + y * bytes_per_line : start + y * bytes_per_line + 4 * width]
        if byte_order == 0:  # LSBFirst: B, G, R, X
            rows.append(bytes(c for x in range(width) for c in (line[4 * x + 2], line[4 * x + 1], line[4 * x])))
        else:  # MSBFirst: X, R, G, B
            rows.append(bytes(c for x in range(width) for c in line[4 * x + 1 : 4 * x + 4]))
    return width, height, rows


def write_png(path, width, height, rows):
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)

    raw = b"".join(b"\x00" + r for r in rows)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")
    open(path, "wb").write(png)


def main():
    width, height, rows = read_xwd(sys.argv[1])
    write_png(sys.argv[2], width, height, rows)
    colours = {r[i : i + 3] for r in rows[::8] for i in range(0, len(r), 24)}
    print(f"{sys.argv[1]}: {width}x{height}, {len(colours)} distinct colours (sampled)")
    sys.exit(0 if len(colours) >= 64 else 1)


if __name__ == "__main__":
    main()
