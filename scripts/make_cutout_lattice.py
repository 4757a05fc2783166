#!/usr/bin/env python3
"""Writes assets/scenes/cutout_lattice.{gltf,bin} and lattice.png (standard library only).

A cut-out occluder as foliage cards and fences are drawn in glTF assets: one quad of two
triangles whose base-colour texture's alpha is a lattice (alphaMode MASK, alphaCutoff 0.5),
held 1.2 m over a low-poly floor under a small quad light, so that the light falls through
its 16 square openings onto the floor. A box beside it is solid, for comparison.

Run from the repository root: python3 scripts/make_cutout_lattice.py
"""

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from make_textured_materials import OUT, Buffer, box, grid, look_at, png  # noqa: E402

# 17x17 texels: bars one texel wide every 4 texels, edges included (alpha 255), 4x4 openings of
# 3x3 texels (alpha 0).
LATTICE = 17


def lattice_texel(x, y):
    bar = x % 4 == 0 or y % 4 == 0
    return (150, 105, 60, 255) if bar else (150, 105, 60, 0)


def main():
    png(OUT / "lattice.png", LATTICE, LATTICE, lattice_texel)
    buf = Buffer()
    meshes = []

    def mesh(pos, nor, idx, material, uv=None):
        attrs = {"POSITION": buf.add("fff", pos, "VEC3", 34962, True), "NORMAL": buf.add("fff", nor, "VEC3", 34962)}
        if uv:
            attrs["TEXCOORD_0"] = buf.add("ff", uv, "VEC2", 34962)
        meshes.append({"primitives": [{"attributes": attrs, "indices": buf.add("I", idx, "SCALAR", 34963),
                                       "material": material}]})
        return len(meshes) - 1

    p, n, uv, i = grid(4, 6.0, 1.0)
    floor = mesh(p, n, i, 0, uv=uv)
    # The lattice: a 1.6 m square facing up, UVs spanning the texture once (wrap: clamp).
    h = 0.8
    quad = [(-h, 0.0, -h), (h, 0.0, -h), (h, 0.0, h), (-h, 0.0, h)]
    lattice = mesh(quad, [(0, 1, 0)] * 4, [0, 3, 2, 0, 2, 1], 1, uv=[(0, 0), (1, 0), (1, 1), (0, 1)])
    p, n, _, i = box(0.3)
    cube = mesh(p, n, i, 2)
    s = 0.15
    light = mesh([(-s, 0.0, -s), (s, 0.0, -s), (s, 0.0, s), (-s, 0.0, s)], [(0, -1, 0)] * 4, [0, 1, 2, 0, 2, 3], 3)

    materials = [
        {"name": "floor", "pbrMetallicRoughness": {"baseColorFactor": [0.75, 0.75, 0.72, 1.0], "metallicFactor": 0.0,
                                                    "roughnessFactor": 0.9}},
        {"name": "lattice", "alphaMode": "MASK", "alphaCutoff": 0.5, "doubleSided": True,
         "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0, "roughnessFactor": 0.8}},
        {"name": "box", "pbrMetallicRoughness": {"baseColorFactor": [0.3, 0.45, 0.8, 1.0], "metallicFactor": 0.0,
                                                  "roughnessFactor": 0.6}},
        {"name": "light", "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1]}, "emissiveFactor": [1.0, 0.96, 0.9],
         "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 400.0}}},
    ]
    eye = [0.0, 3.6, 4.2]
    nodes = [
        {"name": "floor", "mesh": floor},
        {"name": "lattice", "mesh": lattice, "translation": [0.0, 1.2, 0.0]},
        {"name": "box", "mesh": cube, "translation": [1.9, 0.3, 0.4]},
        {"name": "light", "mesh": light, "translation": [0.0, 4.0, 0.0]},
        {"name": "camera", "camera": 0, "translation": eye, "rotation": look_at(eye, [0.0, 0.5, 0.0])},
    ]
    gltf = {
        "asset": {"version": "2.0", "generator": "kage scripts/make_cutout_lattice.py"},
        "extensionsUsed": ["KHR_materials_emissive_strength"],
        "scene": 0, "scenes": [{"nodes": list(range(len(nodes)))}], "nodes": nodes, "meshes": meshes,
        "materials": materials,
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "aspectRatio": 16 / 9, "znear": 0.05}}],
        "samplers": [{"magFilter": 9729, "minFilter": 9729, "wrapS": 33071, "wrapT": 33071}],
        "images": [{"uri": "lattice.png"}],
        "textures": [{"sampler": 0, "source": 0}],
        "buffers": [{"uri": "cutout_lattice.bin", "byteLength": len(buf.data)}],
        "bufferViews": buf.views, "accessors": buf.accessors,
    }
    (OUT / "cutout_lattice.bin").write_bytes(bytes(buf.data))
    (OUT / "cutout_lattice.gltf").write_text(json.dumps(gltf, indent=1) + "\n")


if __name__ == "__main__":
    main()
