//! Piecewise-constant distributions in 1D and 2D (pbrt's `PiecewiseConstant1D/2D`), with the
//! inverse of every sampling map so that round trips can be tested.

use glam::Vec2;

/// A piecewise-constant density over [0, 1) with `n` equal cells.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    func: Vec<f32>,
    cdf: Vec<f64>,
    integral: f64,
}

impl Distribution1D {
    /// Builds from non-negative cell values; an all-zero (or empty) input becomes uniform.
    pub fn new(values: &[f32]) -> Self {
        let n = values.len().max(1);
        let sane = |v: f32| if v.is_finite() && v > 0.0 { v } else { 0.0 };
        let mut func: Vec<f32> = values.iter().map(|&v| sane(v)).collect();
        func.resize(n, 0.0);
        let mut cdf = vec![0.0f64; n + 1];
        for i in 0..n {
            cdf[i + 1] = cdf[i] + func[i] as f64 / n as f64;
        }
        let mut integral = cdf[n];
        if integral <= 0.0 {
            func.iter_mut().for_each(|f| *f = 1.0);
            cdf.iter_mut().enumerate().for_each(|(i, c)| *c = i as f64 / n as f64);
            integral = 1.0;
        } else {
            cdf.iter_mut().for_each(|c| *c /= integral);
        }
        Self { func, cdf, integral }
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.func.len()
    }

    /// Always false: a distribution has at least one cell.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// ∫ f over [0, 1).
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// Maps `u` ∈ [0,1) to `(x, pdf, cell)`.
    pub fn sample(&self, u: f32) -> (f32, f32, usize) {
        let u = u as f64;
        let n = self.len();
        // Last cdf entry ≤ u, skipping zero-width cells.
        let cell = self.cdf.partition_point(|&c| c <= u).saturating_sub(1).min(n - 1);
        let (lo, hi) = (self.cdf[cell], self.cdf[cell + 1]);
        let du = if hi > lo { (u - lo) / (hi - lo) } else { 0.0 };
        let x = ((cell as f64 + du) / n as f64).min(1.0 - f64::EPSILON) as f32;
        (x, self.pdf_cell(cell), cell)
    }

    /// Density at cell `cell`.
    pub fn pdf_cell(&self, cell: usize) -> f32 {
        (self.func[cell] as f64 / self.integral) as f32
    }

    /// Density at `x` ∈ [0,1).
    pub fn pdf(&self, x: f32) -> f32 {
        self.pdf_cell(self.cell_of(x))
    }

    /// Inverse of [`Self::sample`]: the `u` that maps to `x` (the CDF at `x`).
    pub fn invert(&self, x: f32) -> f32 {
        let cell = self.cell_of(x);
        let n = self.len() as f64;
        let t = x as f64 * n - cell as f64;
        (self.cdf[cell] + t * (self.cdf[cell + 1] - self.cdf[cell])) as f32
    }

    fn cell_of(&self, x: f32) -> usize {
        ((x.clamp(0.0, 1.0) * self.len() as f32) as usize).min(self.len() - 1)
    }
}

/// A piecewise-constant density over [0,1)² on a `width × height` grid (row-major, row = v).
#[derive(Clone, Debug)]
pub struct Distribution2D {
    rows: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl Distribution2D {
    /// Builds from row-major non-negative values.
    pub fn new(values: &[f32], width: usize, height: usize) -> Self {
        assert_eq!(values.len(), width * height, "grid size mismatch");
        let rows: Vec<Distribution1D> = values.chunks(width).map(Distribution1D::new).collect();
        let row_integrals: Vec<f32> = values
            .chunks(width)
            .map(|r| {
                r.iter().map(|&v| if v.is_finite() { v.max(0.0) as f64 } else { 0.0 }).sum::<f64>() as f32
                    / width as f32
            })
            .collect();
        Self { rows, marginal: Distribution1D::new(&row_integrals) }
    }

    /// Maps `u` ∈ [0,1)² to `(point, pdf)`; the point's x is the column axis, y the row axis.
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let (y, pdf_y, row) = self.marginal.sample(u.y);
        let (x, pdf_x, _) = self.rows[row].sample(u.x);
        (Vec2::new(x, y), pdf_x * pdf_y)
    }

    /// Density at `p`.
    pub fn pdf(&self, p: Vec2) -> f32 {
        let row = self.marginal.cell_of(p.y);
        self.marginal.pdf_cell(row) * self.rows[row].pdf(p.x)
    }

    /// Inverse of [`Self::sample`].
    pub fn invert(&self, p: Vec2) -> Vec2 {
        let row = self.marginal.cell_of(p.y);
        Vec2::new(self.rows[row].invert(p.x), self.marginal.invert(p.y))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_d_round_trip_and_pdf() {
        let d = Distribution1D::new(&[0.0, 1.0, 3.0, 0.0, 4.0]);
        assert!((d.integral() - 8.0 / 5.0).abs() < 1e-12);
        for i in 1..1000 {
            let u = i as f32 / 1000.0;
            let (x, pdf, cell) = d.sample(u);
            assert!(d.pdf_cell(cell) > 0.0 && pdf > 0.0, "never samples a zero cell");
            assert!((d.invert(x) - u).abs() < 1e-5, "u {u} x {x}");
        }
    }

    #[test]
    fn zero_and_nan_inputs_become_uniform() {
        let d = Distribution1D::new(&[0.0, f32::NAN, -1.0]);
        assert_eq!(d.pdf(0.5), 1.0);
    }

    #[test]
    fn two_d_round_trip_and_normalisation() {
        let vals: Vec<f32> = (0..12).map(|i| ((i * 7) % 5) as f32).collect();
        let d = Distribution2D::new(&vals, 4, 3);
        let mut integral = 0.0;
        for j in 0..3 {
            for i in 0..4 {
                integral += d.pdf(Vec2::new((i as f32 + 0.5) / 4.0, (j as f32 + 0.5) / 3.0)) / 12.0;
            }
        }
        assert!((integral - 1.0).abs() < 1e-5);
        for k in 1..200 {
            let u = Vec2::new((k as f32 * 0.618).fract(), k as f32 / 200.0);
            let (p, pdf) = d.sample(u);
            assert!((pdf - d.pdf(p)).abs() < 1e-5);
            assert!((d.invert(p) - u).abs().max_element() < 1e-4);
        }
    }
}
