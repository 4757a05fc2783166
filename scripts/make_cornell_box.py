#!/usr/bin/env python3
"""Writes the Cornell box as a glTF file, from the Cornell Program of Computer Graphics'
published measurements (https://www.graphics.cornell.edu/online/box/data.html): the room's
five walls as two triangles each, the short and the tall block, the 130 × 105 mm light in the
ceiling's plane lowered by --light-drop millimetres (default 1, so that it does not lie in
the ceiling), and the published camera (35 mm lens, 25 mm film, at (278, 273, −800) looking
along +z). Lengths are converted from millimetres to metres; the published coordinates are
kept (x to the camera's left, so the red wall is on the left).

Reflectances and the light's radiance are the RGB values scenes commonly use for the box
(white 0.725; red 0.63, 0.065, 0.05; green 0.14, 0.45, 0.091; light 18.4, 14.0, 6.75), with
no specular lobe (KHR_materials_specular factor 0): the published box is Lambertian.

    python3 scripts/make_cornell_box.py OUT.gltf [--reach fixed] [--light-drop MM]

--reach fixed declares the light's reach as fixed (extras.kage.light_reach).
"""
import argparse
import json
import math

from gltf_buffer import Buffer

WHITE, RED, GREEN = [0.725] * 3, [0.63, 0.065, 0.05], [0.14, 0.45, 0.091]
LIGHT_RADIANCE = [18.4, 14.0, 6.75]

# The published quads (millimetres), each with the side its surface faces: "in" for the
# room's walls (toward the room's centre), "out" for the blocks' faces (away from the block).
ROOM = {
    "floor": ([[552.8, 0, 0], [0, 0, 0], [0, 0, 559.2], [549.6, 0, 559.2]], WHITE),
    "ceiling": ([[556, 548.8, 0], [556, 548.8, 559.2], [0, 548.8, 559.2], [0, 548.8, 0]], WHITE),
    "back_wall": ([[549.6, 0, 559.2], [0, 0, 559.2], [0, 548.8, 559.2], [556, 548.8, 559.2]], WHITE),
    "right_wall": ([[0, 0, 559.2], [0, 0, 0], [0, 548.8, 0], [0, 548.8, 559.2]], GREEN),
    "left_wall": ([[552.8, 0, 0], [549.6, 0, 559.2], [556, 548.8, 559.2], [556, 548.8, 0]], RED),
}
SHORT_BLOCK = [
    [[130, 165, 65], [82, 165, 225], [240, 165, 272], [290, 165, 114]],
    [[290, 0, 114], [290, 165, 114], [240, 165, 272], [240, 0, 272]],
    [[130, 0, 65], [130, 165, 65], [290, 165, 114], [290, 0, 114]],
    [[82, 0, 225], [82, 165, 225], [130, 165, 65], [130, 0, 65]],
    [[240, 0, 272], [240, 165, 272], [82, 165, 225], [82, 0, 225]],
]
TALL_BLOCK = [
    [[423, 330, 247], [265, 330, 296], [314, 330, 456], [472, 330, 406]],
    [[423, 0, 247], [423, 330, 247], [472, 330, 406], [472, 0, 406]],
    [[472, 0, 406], [472, 330, 406], [314, 330, 456], [314, 0, 456]],
    [[314, 0, 456], [314, 330, 456], [265, 330, 296], [265, 0, 296]],
    [[265, 0, 296], [265, 330, 296], [423, 330, 247], [423, 0, 247]],
]
LIGHT = [[343, 548.8, 227], [343, 548.8, 332], [213, 548.8, 332], [213, 548.8, 227]]
ROOM_CENTRE = [278, 274.4, 279.6]


def sub(a, b):
    return [x - y for x, y in zip(a, b)]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def unit(a):
    n = math.sqrt(dot(a, a))
    return [x / n for x in a]


def quad(points, toward):
    """Two triangles of a planar quad, wound counter-clockwise seen from the side `toward`
    points to (a vector from the quad's centre), with its unit normal: 4 vertices (metres)."""
    n = unit(cross(sub(points[1], points[0]), sub(points[2], points[0])))
    if dot(n, toward) < 0:
        points, n = points[::-1], [-x for x in n]
    return [[c / 1000 for c in p] for p in points], [n] * 4, [0, 1, 2, 0, 2, 3]


def centre(points):
    return [sum(p[k] for p in points) / len(points) for k in range(3)]


def merge(parts):
    pos, nrm, idx = [], [], []
    for p, n, i in parts:
        idx += [len(pos) + k for k in i]
        pos += p
        nrm += n
    return pos, nrm, idx


def block(faces):
    c = centre([p for f in faces for p in f])
    return merge([quad(f, sub(centre(f), c)) for f in faces])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out")
    ap.add_argument("--reach", choices=["none", "fixed"], default="none")
    ap.add_argument("--light-drop", type=float, default=1.0, help="millimetres below the ceiling")
    args = ap.parse_args()
    light = [[x, y - args.light_drop, z] for x, y, z in LIGHT]
    shapes = [(name, quad(q, sub(ROOM_CENTRE, centre(q))), colour) for name, (q, colour) in ROOM.items()]
    shapes += [("short_block", block(SHORT_BLOCK), WHITE), ("tall_block", block(TALL_BLOCK), WHITE)]
    shapes.append(("light", quad(light, [0, -1, 0]), None))
    buffer, meshes, materials, nodes = Buffer(), [], [], []
    for name, primitive, colour in shapes:
        attrs, indices = buffer.primitive(*primitive)
        if colour is None:
            strength = max(LIGHT_RADIANCE)
            materials.append({"name": name, "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1]},
                              "emissiveFactor": [c / strength for c in LIGHT_RADIANCE],
                              "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": strength}}})
        else:
            materials.append({"name": name, "pbrMetallicRoughness": {
                "baseColorFactor": colour + [1], "metallicFactor": 0.0, "roughnessFactor": 1.0},
                "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}})
        meshes.append({"name": name, "primitives": [{"attributes": attrs, "indices": indices,
                                                     "material": len(materials) - 1}]})
        node = {"name": name, "mesh": len(meshes) - 1}
        if colour is None and args.reach == "fixed":
            node["extras"] = {"kage": {"light_reach": "fixed"}}
        nodes.append(node)
    # The published camera looks along +z; a glTF camera looks along its local −z: turned 180°
    # about y. Field of view from the 35 mm lens and the 25 mm film.
    nodes.append({"name": "camera", "camera": 0, "translation": [0.278, 0.273, -0.8], "rotation": [0, 1, 0, 0]})
    doc = {
        "asset": {"version": "2.0", "generator": "kage scripts/make_cornell_box.py"},
        "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_materials_specular"],
        "scene": 0, "scenes": [{"nodes": list(range(len(nodes)))}], "nodes": nodes,
        "meshes": meshes, "materials": materials,
        **buffer.tables(),
        "cameras": [{"type": "perspective",
                     "perspective": {"yfov": 2 * math.atan(12.5 / 35), "znear": 0.01, "aspectRatio": 1.0}}],
        "buffers": buffer.buffers(),
    }
    with open(args.out, "w") as f:
        json.dump(doc, f)


if __name__ == "__main__":
    main()
