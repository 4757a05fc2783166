#!/usr/bin/env python3
"""Writes assets/scenes/textured_materials.{gltf,bin} and its PNG textures (standard library only).

A low-poly, textured scene as glTF assets usually are, under a quad light (and whatever
environment `--env` adds): every material feature kage reads appears once —

* floor: 10x10 quads, sRGB base-colour checker texture repeated 4x (TEXCOORD_0, REPEAT);
* sphere: gold factor x a metallic-roughness texture of bands (metal/rough alternate);
* box: vertex colours (COLOR_0, one colour per face) on a white rough dielectric;
* poster: a base-colour texture read through TEXCOORD_1 with KHR_texture_transform.

Run from the repository root: python3 scripts/make_textured_materials.py
"""

import json
import math
import struct
import zlib
from pathlib import Path

OUT = Path("assets/scenes")


def png(path, width, height, pixel):
    """An 8-bit PNG of pixel(x, y) -> (r, g, b), or (r, g, b, a) for RGBA."""
    rows = b"".join(b"\x00" + bytes(c for x in range(width) for c in pixel(x, y)) for y in range(height))
    colour_type = 6 if len(pixel(0, 0)) == 4 else 2

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, colour_type, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows, 9)) + chunk(b"IEND", b""))


class Buffer:
    def __init__(self):
        self.data, self.views, self.accessors = bytearray(), [], []

    def add(self, fmt, rows, kind, target, minmax=False):
        while len(self.data) % 4:
            self.data.append(0)
        start = len(self.data)
        for r in rows:
            self.data += struct.pack("<" + fmt, *r) if isinstance(r, (tuple, list)) else struct.pack("<" + fmt, r)
        self.views.append({"buffer": 0, "byteOffset": start, "byteLength": len(self.data) - start, "target": target})
        acc = {"bufferView": len(self.views) - 1, "count": len(rows), "type": kind,
               "componentType": 5125 if fmt == "I" else 5126}
        if minmax:
            acc["min"] = [min(r[i] for r in rows) for i in range(3)]
            acc["max"] = [max(r[i] for r in rows) for i in range(3)]
        self.accessors.append(acc)
        return len(self.accessors) - 1


def look_at(eye, target):
    """The rotation (x, y, z, w) turning a glTF camera (looking down -Z, +Y up) from eye to target."""
    sub = lambda a, b: [a[k] - b[k] for k in range(3)]
    unit = lambda a: [c / math.sqrt(sum(x * x for x in a)) for c in a]
    cross = lambda a, b: [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    z = unit(sub(eye, target))
    x = unit(cross([0, 1, 0], z))
    y = cross(z, x)
    m = [[x[0], y[0], z[0]], [x[1], y[1], z[1]], [x[2], y[2], z[2]]]
    w = math.sqrt(max(0.0, 1 + m[0][0] + m[1][1] + m[2][2])) / 2
    return [(m[2][1] - m[1][2]) / (4 * w), (m[0][2] - m[2][0]) / (4 * w), (m[1][0] - m[0][1]) / (4 * w), w]


def grid(n, size, uv_repeat):
    pos, nor, uv, idx = [], [], [], []
    for j in range(n + 1):
        for i in range(n + 1):
            pos.append((size * (i / n - 0.5), 0.0, size * (j / n - 0.5)))
            nor.append((0.0, 1.0, 0.0))
            uv.append((uv_repeat * i / n, uv_repeat * j / n))
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            idx += [a, a + n + 1, a + 1, a + 1, a + n + 1, a + n + 2]
    return pos, nor, uv, idx


def sphere(r, nu, nv):
    pos, nor, uv, idx = [], [], [], []
    for j in range(nv + 1):
        th = math.pi * j / nv
        for i in range(nu + 1):
            ph = 2 * math.pi * i / nu
            n = (math.sin(th) * math.cos(ph), math.cos(th), -math.sin(th) * math.sin(ph))
            pos.append(tuple(r * c for c in n))
            nor.append(n)
            uv.append((i / nu, j / nv))
    for j in range(nv):
        for i in range(nu):
            a, b = j * (nu + 1) + i, (j + 1) * (nu + 1) + i
            if j > 0:
                idx += [a, b, a + 1]
            if j < nv - 1:
                idx += [a + 1, b, b + 1]
    return pos, nor, uv, idx


def box(h):
    faces = [((1, 0, 0), (0, 0, -1), (0, 1, 0)), ((-1, 0, 0), (0, 0, 1), (0, 1, 0)), ((0, 1, 0), (1, 0, 0), (0, 0, -1)),
             ((0, -1, 0), (1, 0, 0), (0, 0, 1)), ((0, 0, 1), (1, 0, 0), (0, 1, 0)), ((0, 0, -1), (-1, 0, 0), (0, 1, 0))]
    colours = [(0.9, 0.2, 0.15), (0.2, 0.7, 0.25), (0.95, 0.85, 0.2), (0.5, 0.5, 0.5), (0.2, 0.35, 0.9), (0.85, 0.3, 0.8)]
    pos, nor, col, idx = [], [], [], []
    for (n, u, v), c in zip(faces, colours):
        base = len(pos)
        for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            pos.append(tuple(h * (n[k] + su * u[k] + sv * v[k]) for k in range(3)))
            nor.append(n)
            col.append(c)
        idx += [base, base + 1, base + 2, base, base + 2, base + 3]
    return pos, nor, col, idx


def main():
    png(OUT / "checker.png", 32, 32, lambda x, y: (200, 190, 170) if (x // 16 + y // 16) % 2 == 0 else (60, 80, 110))
    # Metallic-roughness: G = roughness, B = metalness, in bands along v.
    png(OUT / "metal_rough.png", 4, 16, lambda x, y: (0, 70, 255) if (y // 4) % 2 == 0 else (0, 200, 0))
    png(OUT / "poster.png", 16, 16, lambda x, y: (230, 120, 40) if (x // 8 + y // 8) % 2 == 0 else (40, 140, 200))

    buf = Buffer()
    meshes = []

    def mesh(pos, nor, idx, material, uv=None, uv1=None, col=None):
        attrs = {"POSITION": buf.add("fff", pos, "VEC3", 34962, True), "NORMAL": buf.add("fff", nor, "VEC3", 34962)}
        if uv:
            attrs["TEXCOORD_0"] = buf.add("ff", uv, "VEC2", 34962)
        if uv1:
            attrs["TEXCOORD_1"] = buf.add("ff", uv1, "VEC2", 34962)
        if col:
            attrs["COLOR_0"] = buf.add("fff", col, "VEC3", 34962)
        ind = buf.add("I", idx, "SCALAR", 34963)
        meshes.append({"primitives": [{"attributes": attrs, "indices": ind, "material": material}]})
        return len(meshes) - 1

    p, n, uv, i = grid(10, 6.0, 4.0)
    floor = mesh(p, n, i, 0, uv=uv)
    p, n, uv, i = sphere(0.6, 24, 12)
    ball = mesh(p, n, i, 1, uv=uv)
    p, n, c, i = box(0.35)
    cube = mesh(p, n, i, 2, col=c)
    quad = [(-0.8, -0.6, 0.0), (0.8, -0.6, 0.0), (0.8, 0.6, 0.0), (-0.8, 0.6, 0.0)]
    poster = mesh(quad, [(0, 0, 1)] * 4, [0, 1, 2, 0, 2, 3], 3, uv=[(0, 0)] * 4, uv1=[(0, 1), (1, 1), (1, 0), (0, 0)])
    light_quad = [(-0.5, 0.0, -0.5), (0.5, 0.0, -0.5), (0.5, 0.0, 0.5), (-0.5, 0.0, 0.5)]  # emits down
    light = mesh(light_quad, [(0, -1, 0)] * 4, [0, 1, 2, 0, 2, 3], 4)

    materials = [
        {"name": "checker floor", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0,
                                                            "roughnessFactor": 0.8}},
        {"name": "banded gold", "pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.78, 0.34, 1.0],
                                                          "metallicRoughnessTexture": {"index": 1}}},
        {"name": "vertex colours", "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.6}},
        {"name": "poster", "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.9, "baseColorTexture": {
            "index": 2, "texCoord": 1,
            "extensions": {"KHR_texture_transform": {"offset": [0.5, 0.0], "rotation": 0.3, "scale": [2.0, 2.0]}}}}},
        {"name": "light", "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1]}, "emissiveFactor": [1.0, 0.95, 0.85],
         "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 80.0}}},
    ]
    eye = [2.4, 2.4, 3.8]
    nodes = [
        {"name": "floor", "mesh": floor},
        {"name": "sphere", "mesh": ball, "translation": [-0.7, 0.6, 0.2]},
        {"name": "box", "mesh": cube, "translation": [0.9, 0.35, 0.5], "rotation": [0, 0.3826834, 0, 0.9238795]},
        {"name": "poster", "mesh": poster, "translation": [0.3, 0.9, -1.6]},
        {"name": "light", "mesh": light, "translation": [0.2, 2.6, 0.3]},
        {"name": "camera", "camera": 0, "translation": eye, "rotation": look_at(eye, [0.0, 0.5, -0.2])},
    ]
    gltf = {
        "asset": {"version": "2.0", "generator": "kage scripts/make_textured_materials.py"},
        "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_texture_transform"],
        "scene": 0, "scenes": [{"nodes": list(range(len(nodes)))}], "nodes": nodes, "meshes": meshes,
        "materials": materials,
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.75, "aspectRatio": 16 / 9, "znear": 0.05}}],
        "samplers": [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}],
        "images": [{"uri": "checker.png"}, {"uri": "metal_rough.png"}, {"uri": "poster.png"}],
        "textures": [{"sampler": 0, "source": k} for k in range(3)],
        "buffers": [{"uri": "textured_materials.bin", "byteLength": len(buf.data)}],
        "bufferViews": buf.views, "accessors": buf.accessors,
    }
    (OUT / "textured_materials.bin").write_bytes(bytes(buf.data))
    (OUT / "textured_materials.gltf").write_text(json.dumps(gltf, indent=1) + "\n")


if __name__ == "__main__":
    main()
