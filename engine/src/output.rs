//! Writing results: EXR (linear radiance), PNG (exposure + sRGB), and per-vertex CSV — each
//! through [`write_atomically`].

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

/// Writes `path` through `fill`, into a temporary file beside it that is then renamed over
/// `path`: a reader never sees half a file, a failed write leaves the old file, and a symlink
/// at `path` is replaced, never written through.
pub fn write_atomically(
    path: &Path,
    fill: impl FnOnce(&mut std::fs::File) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let mut file = tempfile::Builder::new().prefix(".kage-").suffix(".partial").tempfile_in(dir)?;
    fill(file.as_file_mut())?;
    file.as_file().sync_all()?;
    file.persist(path).map(drop).map_err(|e| e.error)
}

/// Writes an image by extension: `.exr` keeps linear radiance; `.png` applies `2^exposure`,
/// clamps and encodes sRGB.
pub fn write_image(path: &Path, width: usize, height: usize, pixels: &[Vec3], exposure: f32) -> Result<()> {
    let format = ImageFormat::of(path)?;
    let (w, h) = (width as u32, height as u32);
    let result = write_atomically(path, |file| {
        let mut out = std::io::BufWriter::new(file);
        let encoded = match format {
            ImageFormat::Exr => {
                let data: Vec<f32> = pixels.iter().flat_map(|p| p.to_array()).collect();
                let image = image::Rgb32FImage::from_raw(w, h, data).expect("size matches");
                image.write_to(&mut out, image::ImageFormat::OpenExr)
            }
            ImageFormat::Png => {
                let scale = exposure.exp2();
                let data: Vec<u8> = pixels
                    .iter()
                    .flat_map(|p| (*p * scale).to_array().map(|c| (display_srgb(c) * 255.0 + 0.5) as u8))
                    .collect();
                image::RgbImage::from_raw(w, h, data).expect("size matches").write_to(&mut out, image::ImageFormat::Png)
            }
        };
        encoded.map_err(std::io::Error::other)?;
        out.flush()
    });
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
    let result = write_atomically(path, |file| {
        let mut w = std::io::BufWriter::new(file);
        writeln!(w, "{VERTEX_CSV_HEADER}")?;
        for r in rows {
            let (p, c) = (r.position, r.radiance);
            writeln!(
                w,
                "{},{},{},{},{},{},{},{},{},{}",
                r.node, r.mesh, r.primitive, r.vertex, p.x, p.y, p.z, c.x, c.y, c.z
            )?;
        }
        w.flush()
    });
    result.map_err(|e| Error::io(path, e))
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

    /// An image written over a symlink replaces the link and leaves its target alone; a write
    /// that fails leaves the old file and no temporary file behind.
    #[cfg(unix)]
    #[test]
    fn outputs_replace_symlinks_and_failed_writes_change_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let victim = dir.path().join("victim.txt");
        std::fs::write(&victim, "keep").unwrap();
        let link = dir.path().join("out.png");
        std::os::unix::fs::symlink(&victim, &link).unwrap();
        write_image(&link, 2, 1, &[Vec3::ONE, Vec3::ZERO], 0.0).unwrap();
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep");
        assert!(std::fs::read(&link).unwrap().starts_with(b"\x89PNG"));
        let failed = write_atomically(&victim, |f| {
            f.write_all(b"half")?;
            Err(std::io::Error::other("disk full"))
        });
        assert!(failed.is_err());
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2, "no temporary file left");
    }

    #[test]
    fn csv_round_trips_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("v.csv");
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
    }

    #[test]
    fn srgb_endpoints() {
        assert_eq!(display_srgb(0.0), 0.0);
        assert!((display_srgb(1.0) - 1.0).abs() < 1e-6);
        assert_eq!(display_srgb(2.0), display_srgb(1.0));
        assert_eq!(display_srgb(f32::NAN), 0.0);
    }
}
