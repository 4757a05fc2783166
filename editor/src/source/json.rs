//! The source glTF's JSON as a save edits it: the top-level object and its arrays as objects
//! whose values are raw text, so that whatever is not edited is written back as it was read.
//! Geometry added in the editor goes into one new buffer, a `data:` URI (nothing beside the
//! file is written, so the save stays one atomic rename).

use base64::Engine as _;
use indexmap::IndexMap;
use serde_json::value::{RawValue, to_raw_value};
use std::collections::{HashMap, HashSet};

/// A JSON object: keys in source order, values as their raw text.
pub(super) type Object = IndexMap<String, Box<RawValue>>;

/// The top-level arrays a save may edit.
const ARRAYS: [&str; 7] = ["scenes", "nodes", "meshes", "materials", "accessors", "bufferViews", "buffers"];

/// glTF's component types and buffer view targets used by added geometry.
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// The document being edited.
pub(super) struct GltfJson {
    top: Object,
    arrays: HashMap<&'static str, Vec<Object>>,
    touched: HashSet<&'static str>,
    /// Bytes of the buffer added for new geometry, and its index once it has one.
    bin: Vec<u8>,
    bin_index: Option<usize>,
}

impl GltfJson {
    /// Parses the JSON chunk.
    pub(super) fn parse(json: &[u8]) -> serde_json::Result<Self> {
        let top: Object = serde_json::from_slice(json)?;
        let mut arrays = HashMap::new();
        for key in ARRAYS {
            let parsed: Vec<Object> = top.get(key).map_or(Ok(Vec::new()), |raw| serde_json::from_str(raw.get()))?;
            arrays.insert(key, parsed);
        }
        Ok(Self { top, arrays, touched: HashSet::new(), bin: Vec::new(), bin_index: None })
    }

    /// The JSON to write: edited arrays serialised again, the others as they were read.
    pub(super) fn into_json(mut self) -> serde_json::Result<Vec<u8>> {
        if let Some(index) = self.bin_index {
            let uri = format!(
                "data:application/octet-stream;base64,{}",
                base64::engine::general_purpose::STANDARD.encode(&self.bin)
            );
            let mut buffer = Object::new();
            set(&mut buffer, "byteLength", self.bin.len());
            set(&mut buffer, "uri", uri);
            self.array("buffers")[index] = buffer;
        }
        for key in ARRAYS.into_iter().filter(|k| self.touched.contains(k)) {
            self.top.insert(key.to_string(), to_raw_value(&self.arrays[key])?);
        }
        serde_json::to_vec(&self.top)
    }

    /// Top-level array `key`, to edit (written back by [`Self::into_json`]).
    pub(super) fn array(&mut self, key: &'static str) -> &mut Vec<Object> {
        self.touched.insert(key);
        self.arrays.get_mut(key).expect("one of ARRAYS")
    }

    /// How many entries array `key` has.
    pub(super) fn len(&self, key: &'static str) -> usize {
        self.arrays[key].len()
    }

    /// Appends `object` to array `key`; returns its index.
    pub(super) fn push(&mut self, key: &'static str, object: Object) -> usize {
        let array = self.array(key);
        array.push(object);
        array.len() - 1
    }

    /// Lists `extension` in `extensionsUsed` (once).
    pub(super) fn uses(&mut self, extension: &str) {
        let mut used: Vec<String> =
            self.top.get("extensionsUsed").and_then(|r| serde_json::from_str(r.get()).ok()).unwrap_or_default();
        if !used.iter().any(|u| u == extension) {
            used.push(extension.to_string());
            set(&mut self.top, "extensionsUsed", used);
        }
    }

    /// Removes `nodes` from every scene's root list.
    pub(super) fn drop_roots(&mut self, nodes: &[usize]) {
        if nodes.is_empty() {
            return;
        }
        for scene in self.array("scenes") {
            let roots: Vec<usize> = list(scene, "nodes");
            set(scene, "nodes", roots.into_iter().filter(|n| !nodes.contains(n)).collect::<Vec<_>>());
        }
    }

    /// Adds `node` to the roots of the file's default scene (its first without one).
    pub(super) fn add_root(&mut self, node: usize) {
        let default = self.top.get("scene").and_then(|r| serde_json::from_str::<usize>(r.get()).ok()).unwrap_or(0);
        if self.len("scenes") == 0 {
            self.push("scenes", Object::new());
        }
        let scenes = self.array("scenes");
        let scene = scenes.get_mut(default).expect("the default scene exists in a valid file");
        let mut roots: Vec<usize> = list(scene, "nodes");
        roots.push(node);
        set(scene, "nodes", roots);
    }

    /// Removes `child` from node `parent`'s children.
    pub(super) fn drop_child(&mut self, parent: usize, child: usize) {
        let node = &mut self.array("nodes")[parent];
        let children: Vec<usize> = list(node, "children");
        set(node, "children", children.into_iter().filter(|c| *c != child).collect::<Vec<_>>());
    }

    /// Points primitive `primitive` of mesh `mesh` at material `material`.
    pub(super) fn assign(&mut self, mesh: usize, primitive: usize, material: usize) {
        let mesh = &mut self.array("meshes")[mesh];
        let mut primitives: Vec<Object> = list(mesh, "primitives");
        if let Some(p) = primitives.get_mut(primitive) {
            set(p, "material", material);
        }
        set(mesh, "primitives", primitives);
    }

    /// Appends `data` to the added buffer as a view and an accessor of `count` elements of
    /// `kind` (`"VEC3"`, `"VEC2"`, `"SCALAR"` of u32 indices); returns the accessor's index.
    pub(super) fn accessor(&mut self, data: &[u8], count: usize, kind: &str, bounds: Option<[[f32; 3]; 2]>) -> usize {
        let buffer = match self.bin_index {
            Some(i) => i,
            None => {
                let i = self.push("buffers", Object::new());
                self.bin_index = Some(i);
                i
            }
        };
        let offset = self.bin.len();
        self.bin.extend_from_slice(data);
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        let indices = kind == "SCALAR";
        let mut view = Object::new();
        set(&mut view, "buffer", buffer);
        set(&mut view, "byteOffset", offset);
        set(&mut view, "byteLength", data.len());
        set(&mut view, "target", if indices { ELEMENT_ARRAY_BUFFER } else { ARRAY_BUFFER });
        let view = self.push("bufferViews", view);
        let mut accessor = Object::new();
        set(&mut accessor, "bufferView", view);
        set(&mut accessor, "componentType", if indices { UNSIGNED_INT } else { FLOAT });
        set(&mut accessor, "count", count);
        set(&mut accessor, "type", kind);
        if let Some([lo, hi]) = bounds {
            set(&mut accessor, "min", lo);
            set(&mut accessor, "max", hi);
        }
        self.push("accessors", accessor)
    }
}

/// Sets `key` of `object` to `value` (in place when present, keeping the key order).
pub(super) fn set(object: &mut Object, key: &str, value: impl serde::Serialize) {
    let raw = to_raw_value(&value).expect("numbers, strings and arrays serialise");
    object.insert(key.to_string(), raw);
}

/// Edits `object[key]`, an object (created when absent).
pub(super) fn edit_object(object: &mut Object, key: &str, f: impl FnOnce(&mut Object)) {
    let mut inner: Object = object.get(key).and_then(|r| serde_json::from_str(r.get()).ok()).unwrap_or_default();
    f(&mut inner);
    set(object, key, &inner);
}

/// `object[key]` as a list (empty when absent).
fn list<T: serde::de::DeserializeOwned>(object: &Object, key: &str) -> Vec<T> {
    object.get(key).and_then(|r| serde_json::from_str(r.get()).ok()).unwrap_or_default()
}
