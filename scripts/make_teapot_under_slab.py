#!/usr/bin/env python3
"""Writes the slab-edit scene of docs/benchmarks.md#warm-re-bake-after-moving-one-object: the
paper teapot on its ground (`teapot_quad_light.gltf`, whose buffer it shares), a 1.6 m slab
floating above the teapot's lid, and two quad lights (the teapot scene's own and the same
quad turned half a turn to face the teapot from the other side), none with a declared reach.

    python3 scripts/make_teapot_under_slab.py assets/scenes/teapot_under_slab.gltf
"""
import json
import os
import sys

from gltf_buffer import Buffer
from make_two_triangle_floor import cuboid


def main(out):
    here = os.path.dirname(os.path.abspath(out))
    doc = json.load(open(os.path.join(here, "teapot_quad_light.gltf")))
    slab = Buffer()
    attrs, indices = slab.primitive(*cuboid([0.8, 0.05, 0.35]))
    # The slab's views and accessors follow the teapot scene's, in a second buffer.
    views, accessors = len(doc["bufferViews"]), len(doc["accessors"])
    for view in slab.views:
        doc["bufferViews"].append({**view, "buffer": 1})
    for acc in slab.accessors:
        doc["accessors"].append({**acc, "bufferView": acc["bufferView"] + views})
    attrs = {k: v + accessors for k, v in attrs.items()}
    doc["buffers"] += slab.buffers()
    doc["materials"].append({"name": "slab", "pbrMetallicRoughness": {
        "baseColorFactor": [0.5, 0.5, 0.5, 1], "metallicFactor": 0.0, "roughnessFactor": 1.0},
        "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}})
    doc["meshes"].append({"name": "slab", "primitives": [
        {"attributes": attrs, "indices": indices + accessors, "material": len(doc["materials"]) - 1}]})
    nodes = doc["nodes"]
    light = next(n for n in nodes if n["name"] == "light")
    mirrored = {**light, "name": "light_2", "translation": [-1.5, 4.0, 0.5]}
    # Half a turn about +Y: the tilted quad faces the teapot from the other side.
    mirrored["rotation"] = [0.0, 1.0, 0.0, 0.0]
    nodes.append(mirrored)
    nodes.append({"name": "slab", "mesh": len(doc["meshes"]) - 1, "translation": [0.4, 2.3, -0.3]})
    doc["scenes"][0]["nodes"] = list(range(len(nodes)))
    doc["asset"]["generator"] = "kage scripts/make_teapot_under_slab.py"
    with open(out, "w") as f:
        json.dump(doc, f)


if __name__ == "__main__":
    main(sys.argv[1])
