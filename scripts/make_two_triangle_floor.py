#!/usr/bin/env python3
"""Writes the two-triangle floor scene (tests/tests/receivers.rs) as a glTF file: a floor of
two triangles SIDE metres across, two boxes and a ball on it, a 1 m quad light 3 m up with no
declared reach. Used for docs/benchmarks.md#receiver-refinement (bake time against floor area).

    python3 scripts/make_two_triangle_floor.py SIDE OUT.gltf
"""
import json
import math
import sys

from gltf_buffer import Buffer


def cuboid(h):
    """24 vertices (flat faces), 12 triangles, half-extents h."""
    pos, nrm, idx = [], [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = [0.0, 0.0, 0.0]
            n[axis] = sign
            u, v = [(axis + 1) % 3, (axis + 2) % 3]
            base = len(pos)
            for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = [0.0, 0.0, 0.0]
                p[axis] = sign * h[axis]
                p[u] = a * h[u]
                p[v] = b * h[v]
                pos.append(p)
                nrm.append(n)
            quad = [base, base + 1, base + 2, base, base + 2, base + 3]
            if sign < 0:
                quad = [base, base + 2, base + 1, base, base + 3, base + 2]
            idx += quad
    return pos, nrm, idx


def sphere(r, seg, rings):
    pos, nrm, idx = [], [], []
    for i in range(rings + 1):
        th = math.pi * i / rings
        for j in range(seg + 1):
            ph = 2 * math.pi * j / seg
            n = [math.sin(th) * math.cos(ph), math.cos(th), math.sin(th) * math.sin(ph)]
            pos.append([r * c for c in n])
            nrm.append(n)
    for i in range(rings):
        for j in range(seg):
            a, b = i * (seg + 1) + j, (i + 1) * (seg + 1) + j
            if i > 0:
                idx += [a, a + 1, b]
            if i < rings - 1:
                idx += [a + 1, b + 1, b]
    return pos, nrm, idx


def main(side, out):
    h = side / 2
    meshes = {
        "floor": ([[-h, 0, -h], [-h, 0, h], [h, 0, h], [h, 0, -h]], [[0, 1, 0]] * 4, [0, 1, 2, 0, 2, 3]),
        "box": cuboid([0.4, 0.6, 0.4]),
        "slab": cuboid([0.8, 0.05, 0.3]),
        "ball": sphere(0.35, 16, 8),
        "light": ([[-0.5, 0, -0.5], [0.5, 0, -0.5], [0.5, 0, 0.5], [-0.5, 0, 0.5]], [[0, -1, 0]] * 4, [0, 1, 2, 0, 2, 3]),
    }
    nodes = [("floor", [0, 0, 0], 0.7), ("box", [-0.9, 0.6, 0.3], 0.5), ("slab", [1.0, 0.9, -0.6], 0.5),
             ("ball", [0.4, 0.35, 1.3], 0.6), ("light", [0.2, 3.0, 0.1], None)]
    buffer, gl_meshes, materials, gl_nodes = Buffer(), [], [], []
    for name, t, grey in nodes:
        attrs, indices = buffer.primitive(*meshes[name])
        if grey is None:
            materials.append({"name": "light", "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1]},
                              "emissiveFactor": [1, 1, 1],
                              "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 12.0}}})
        else:
            materials.append({"name": name, "pbrMetallicRoughness": {
                "baseColorFactor": [grey, grey, grey, 1], "metallicFactor": 0.0, "roughnessFactor": 1.0},
                "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}})
        gl_meshes.append({"name": name, "primitives": [{"attributes": attrs, "indices": indices,
                                                        "material": len(materials) - 1}]})
        gl_nodes.append({"name": name, "mesh": len(gl_meshes) - 1, "translation": t})
    # The camera of the test: at (0, 6.5, 6.5) looking at (0, 0, 0.3).
    eye, at = [0.0, 6.5, 6.5], [0.0, 0.0, 0.3]
    pitch = math.atan2(eye[1] - at[1], eye[2] - at[2])
    gl_nodes.append({"name": "camera", "camera": 0, "translation": eye,
                     "rotation": [-math.sin(pitch / 2), 0.0, 0.0, math.cos(pitch / 2)]})
    doc = {
        "asset": {"version": "2.0", "generator": "kage scripts/make_two_triangle_floor.py"},
        "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_materials_specular"],
        "scene": 0, "scenes": [{"nodes": list(range(len(gl_nodes)))}], "nodes": gl_nodes,
        "meshes": gl_meshes, "materials": materials,
        **buffer.tables(),
        "cameras": [{"type": "perspective", "perspective": {"yfov": math.radians(45), "znear": 0.05, "aspectRatio": 16 / 9}}],
        "buffers": buffer.buffers(),
    }
    with open(out, "w") as f:
        json.dump(doc, f)


if __name__ == "__main__":
    main(float(sys.argv[1]), sys.argv[2])
