//! Writing results: EXR (linear radiance), PNG (exposure + sRGB), and per-vertex CSV.

use crate::math::color;
use crate::{Error, Result};
use glam::Vec3;
use std::io::Write;
use std::path::Path;

/// A linear value as a display value in [0, 1]: clamped (NaN → 0), then sRGB-encoded.
pub fn display_srgb(c: f32) -> f32 {
    color::linear_to_srgb(if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) })
}

/// The image formats [`write_image`] writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// OpenEXR, linear radiance.
    Exr,
    /// PNG, exposed and sRGB-encoded.
    Png,
}

impl ImageFormat {
    /// The format `path`'s extension names, or an error naming the file (checked before any
    /// work, so that a long render does not end in a refusal).
    pub fn of(path: &Path) -> Result<Self> {
        match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("exr") => Ok(Self::Exr),
            Some("png") => Ok(Self::Png),
            _ => Err(Error::image(path, "output images must be .exr (linear) or .png (tonemapped sRGB)")),
        }
    }
}

/// Writes an image by extension: `.exr` keeps linear radiance; `.png` applies `2^exposure`,
/// clamps and encodes sRGB.
pub fn write_image(path: &Path, width: usize, height: usize, pixels: &[Vec3], exposure: f32) -> Result<()> {
    let result = match ImageFormat::of(path)? {
        ImageFormat::Exr => {
            let data: Vec<f32> = pixels.iter().flat_map(|p| p.to_array()).collect();
            image::Rgb32FImage::from_raw(width as u32, height as u32, data).expect("size matches").save(path)
        }
        ImageFormat::Png => {
            let scale = exposure.exp2();
            let data: Vec<u8> = pixels
                .iter()
                .flat_map(|p| (*p * scale).to_array().map(|c| (display_srgb(c) * 255.0 + 0.5) as u8))
                .collect();
            image::RgbImage::from_raw(width as u32, height as u32, data).expect("size matches").save(path)
        }
    };
    result.map_err(|e| Error::image(path, format!("cannot write: {e}")))
}

/// One row of the per-vertex CSV.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VertexRow {
    /// glTF node index.
    pub node: u32,
    /// glTF mesh index.
    pub mesh: u32,
    /// Primitive index.
    pub primitive: u32,
    /// Vertex index within the primitive.
    pub vertex: u32,
    /// World position.
    pub position: Vec3,
    /// Linear radiance toward the camera.
    pub radiance: Vec3,
}

/// Header of the per-vertex CSV.
pub const VERTEX_CSV_HEADER: &str = "node,mesh,primitive,vertex,x,y,z,r,g,b";

/// Writes per-vertex results as CSV (`node,mesh,primitive,vertex,x,y,z,r,g,b`).
pub fn write_vertex_csv(path: &Path, rows: &[VertexRow]) -> Result<()> {
    let io = |e| Error::io(path, e);
    let mut w = std::io::BufWriter::new(std::fs::File::create(path).map_err(io)?);
    writeln!(w, "{VERTEX_CSV_HEADER}").map_err(io)?;
    for r in rows {
        let (p, c) = (r.position, r.radiance);
        writeln!(
            w,
            "{},{},{},{},{},{},{},{},{},{}",
            r.node, r.mesh, r.primitive, r.vertex, p.x, p.y, p.z, c.x, c.y, c.z
        )
        .map_err(io)?;
    }
    w.flush().map_err(io)
}

/// Reads a CSV written by [`write_vertex_csv`].
pub fn read_vertex_csv(path: &Path) -> Result<Vec<VertexRow>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut lines = text.lines();
    if lines.next() != Some(VERTEX_CSV_HEADER) {
        return Err(Error::Invalid(format!(
            "{}: not a kage vertex CSV (header must be {VERTEX_CSV_HEADER})",
            path.display()
        )));
    }
    lines
        .enumerate()
        .map(|(i, line)| {
            let bad = || Error::Invalid(format!("{}: line {}: malformed row", path.display(), i + 2));
            let f: Vec<&str> = line.split(',').collect();
            if f.len() != 10 {
                return Err(bad());
            }
            let u = |k: usize| f[k].parse::<u32>().map_err(|_| bad());
            let x = |k: usize| f[k].parse::<f32>().map_err(|_| bad());
            Ok(VertexRow {
                node: u(0)?,
                mesh: u(1)?,
                primitive: u(2)?,
                vertex: u(3)?,
                position: Vec3::new(x(4)?, x(5)?, x(6)?),
                radiance: Vec3::new(x(7)?, x(8)?, x(9)?),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_round_trips_exactly() {
        let dir = std::env::temp_dir().join(format!("kage-csv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("v.csv");
        let rows = vec![VertexRow {
            node: 1,
            mesh: 2,
            primitive: 0,
            vertex: 7,
            position: Vec3::new(0.1, -2.5, 1e-7),
            radiance: Vec3::new(0.3, 1.0 / 3.0, 12.0),
        }];
        write_vertex_csv(&path, &rows).unwrap();
        assert_eq!(read_vertex_csv(&path).unwrap(), rows);
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn srgb_endpoints() {
        assert_eq!(display_srgb(0.0), 0.0);
        assert!((display_srgb(1.0) - 1.0).abs() < 1e-6);
        assert_eq!(display_srgb(2.0), display_srgb(1.0));
        assert_eq!(display_srgb(f32::NAN), 0.0);
    }
}
