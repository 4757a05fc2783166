//! PRT at run time (Tamura, Johan & Nishita; `docs/prt.md`): the per-frame half of diffuse
//! environment shading between rigid groups. A bake holds each vertex's self-shadowed transfer
//! in its group's frame; every frame the environment's SH lighting is rotated into each
//! group's frame ([`Posed`]), the other groups' silhouettes along the environment's regions
//! are rasterised ([`silhouette`]), and a vertex's light is the PRT paper's Eq. 15,
//! `max(0, Ls − Σ_i B_i T(p, w_i) V_o(p, w_i))` ([`Posed::radiance`]).

pub mod glossy;
mod lighting;
mod posed;
pub mod prefilter;
pub mod silhouette;
pub mod sun;

pub use lighting::{Region, Window, fibonacci_direction, to_group_frame};
pub use posed::{Posed, group_silhouettes};
