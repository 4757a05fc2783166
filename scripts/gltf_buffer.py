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
