//! BSPVT at run time: the vertex records' layout ([`layout`]) — BSP visibility trees
//! ([`node`]: their split lines) and the occluders' depth ([`depth`]) — and LTC shading of
//! polygonal lights through them ([`shade`]), or through an exact cube map ([`cube`]); a mesh
//! instance's records together ([`BakedInstance`]).

pub mod cube;
pub mod depth;
pub mod layout;
pub mod node;
mod records;
pub mod shade;

pub use records::BakedInstance;
