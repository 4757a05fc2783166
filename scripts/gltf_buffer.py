"""The one embedded buffer of a glTF document that a scene script writes, built up primitive
by primitive: positions and normals (VEC3 floats) and indices (u32), each in its own buffer
view, positions with their bounds."""
import base64
import struct


class Buffer:
    def __init__(self):
        self.blob, self.views, self.accessors = b"", [], []

    def _view(self, raw, target):
        self.views.append({"buffer": 0, "byteOffset": len(self.blob), "byteLength": len(raw), "target": target})
        self.blob += raw
        return len(self.views) - 1

    def primitive(self, pos, nrm, idx):
        """Appends a primitive's data; returns its attributes and its indices' accessor."""
        attrs = {}
        for key, data in (("POSITION", pos), ("NORMAL", nrm)):
            view = self._view(b"".join(struct.pack("<3f", *p) for p in data), 34962)
            acc = {"bufferView": view, "componentType": 5126, "count": len(data), "type": "VEC3"}
            if key == "POSITION":
                acc["min"] = [min(p[k] for p in data) for k in range(3)]
                acc["max"] = [max(p[k] for p in data) for k in range(3)]
            self.accessors.append(acc)
            attrs[key] = len(self.accessors) - 1
        view = self._view(struct.pack(f"<{len(idx)}I", *idx), 34963)
        self.accessors.append({"bufferView": view, "componentType": 5125, "count": len(idx), "type": "SCALAR"})
        return attrs, len(self.accessors) - 1

    def tables(self):
        """The document's accessors and buffer views."""
        return {"accessors": self.accessors, "bufferViews": self.views}

    def buffers(self):
        """The document's buffers: this one, as a data URI."""
        uri = "data:application/octet-stream;base64," + base64.b64encode(self.blob).decode()
        return [{"byteLength": len(self.blob), "uri": uri}]


def lambertian(name, colour):
    """A diffuse material (no specular layer) of linear RGB albedo `colour`."""
    return {"name": name, "pbrMetallicRoughness": {"baseColorFactor": list(colour) + [1], "metallicFactor": 0.0,
                                                   "roughnessFactor": 1.0},
            "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}}


def emitter(name, radiance):
    """A black emissive material of linear RGB `radiance`."""
    strength = max(radiance)
    return {"name": name, "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1]},
            "emissiveFactor": [c / strength for c in radiance],
            "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": strength}}}


def document(generator, buffer, objects, camera, yfov, aspect):
    """A glTF document of `objects` — (name, (positions, normals, indices), material,
    translation) — each its own mesh and node, and a perspective camera node `camera`
    (translation, rotation)."""
    meshes, materials, nodes = [], [], []
    for name, primitive, material, translation in objects:
        attrs, indices = buffer.primitive(*primitive)
        materials.append(material)
        meshes.append({"name": name, "primitives": [{"attributes": attrs, "indices": indices,
                                                     "material": len(materials) - 1}]})
        nodes.append({"name": name, "mesh": len(meshes) - 1, "translation": list(translation)})
    nodes.append({"name": "camera", "camera": 0, "translation": list(camera[0]), "rotation": list(camera[1])})
    return {
        "asset": {"version": "2.0", "generator": generator},
        "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_materials_specular"],
        "scene": 0, "scenes": [{"nodes": list(range(len(nodes)))}], "nodes": nodes,
        "meshes": meshes, "materials": materials,
        **buffer.tables(),
        "cameras": [{"type": "perspective", "perspective": {"yfov": yfov, "znear": 0.02, "aspectRatio": aspect}}],
        "buffers": buffer.buffers(),
    }
