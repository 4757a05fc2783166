//! Nelder–Mead downhill simplex: a deterministic, derivative-free minimiser with restarts
//! (Nelder & Mead 1965, standard coefficients; restarts from the best point with a fresh
//! simplex, which rescues collapsed simplices). Used to fit LTC matrices and BSPVT lines.

/// Stopping and restart parameters.
#[derive(Clone, Copy, Debug)]
pub struct Options {
    /// Maximum function evaluations per start.
    pub max_evals: usize,
    /// Stop when the simplex's value spread falls below this.
    pub tolerance: f64,
    /// Extra starts from the best point found.
    pub restarts: usize,
}

impl Default for Options {
    fn default() -> Self {
        Self { max_evals: 2000, tolerance: 1e-10, restarts: 2 }
    }
}

/// Result of a minimisation.
#[derive(Clone, Debug, PartialEq)]
pub struct Minimum {
    /// Argument of the best value.
    pub x: Vec<f64>,
    /// Best value (non-finite values are treated as +∞).
    pub value: f64,
    /// Function evaluations used.
    pub evals: usize,
}

/// Minimises `f` from `x0` with initial simplex steps `step` (one per coordinate).
pub fn minimize(mut f: impl FnMut(&[f64]) -> f64, x0: &[f64], step: &[f64], opts: Options) -> Minimum {
    assert_eq!(x0.len(), step.len(), "one step per coordinate");
    let mut eval = |x: &[f64]| {
        let v = f(x);
        if v.is_nan() { f64::INFINITY } else { v }
    };
    let mut best = Minimum { x: x0.to_vec(), value: eval(x0), evals: 1 };
    for _ in 0..=opts.restarts {
        let (x, value, evals) = one_start(&mut eval, &best.x, step, opts);
        best.evals += evals;
        if value <= best.value {
            best.x = x;
            best.value = value;
        }
    }
    best
}

fn one_start(f: &mut impl FnMut(&[f64]) -> f64, x0: &[f64], step: &[f64], opts: Options) -> (Vec<f64>, f64, usize) {
    let n = x0.len();
    let mut simplex: Vec<(Vec<f64>, f64)> = Vec::with_capacity(n + 1);
    simplex.push((x0.to_vec(), f(x0)));
    for i in 0..n {
        let mut x = x0.to_vec();
        x[i] += step[i];
        let v = f(&x);
        simplex.push((x, v));
    }
    let mut evals = n + 1;
    // Trial points live in reused buffers: a BSPVT bake runs millions of short minimisations.
    let lerp = |out: &mut Vec<f64>, a: &[f64], b: &[f64], t: f64| {
        out.clear();
        out.extend(a.iter().zip(b).map(|(a, b)| a + t * (b - a)));
    };
    let (mut centroid, mut reflected, mut trial) = (vec![0.0; n], Vec::with_capacity(n), Vec::with_capacity(n));
    while evals < opts.max_evals {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        if (simplex[n].1 - simplex[0].1).abs() <= opts.tolerance * (1.0 + simplex[0].1.abs()) {
            break;
        }
        for (k, c) in centroid.iter_mut().enumerate() {
            *c = simplex[..n].iter().map(|s| s.0[k]).sum::<f64>() / n as f64;
        }
        let worst = simplex[n].1;
        lerp(&mut reflected, &centroid, &simplex[n].0, -1.0);
        let fr = f(&reflected);
        evals += 1;
        let (point, value) = if fr < simplex[0].1 {
            lerp(&mut trial, &centroid, &simplex[n].0, -2.0);
            let fe = f(&trial);
            evals += 1;
            if fe < fr { (&mut trial, fe) } else { (&mut reflected, fr) }
        } else if fr < simplex[n - 1].1 {
            (&mut reflected, fr)
        } else {
            let (towards, fw) = if fr < worst { (&reflected, fr) } else { (&simplex[n].0, worst) };
            lerp(&mut trial, &centroid, towards, 0.5);
            let fc = f(&trial);
            evals += 1;
            if fc >= fw {
                let (best, rest) = simplex.split_at_mut(1);
                for s in rest {
                    s.0.iter_mut().zip(&best[0].0).for_each(|(x, b)| *x = b + 0.5 * (*x - b));
                    s.1 = f(&s.0);
                }
                evals += n;
                continue;
            }
            (&mut trial, fc)
        };
        // The replaced worst point's buffer becomes scratch.
        std::mem::swap(&mut simplex[n].0, point);
        simplex[n].1 = value;
    }
    simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
    let (x, v) = simplex.swap_remove(0);
    (x, v, evals)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_rosenbrock_minimum() {
        let rosen = |x: &[f64]| (1.0 - x[0]).powi(2) + 100.0 * (x[1] - x[0] * x[0]).powi(2);
        let m = minimize(rosen, &[-1.2, 1.0], &[0.5, 0.5], Options { max_evals: 5000, ..Default::default() });
        assert!((m.x[0] - 1.0).abs() < 1e-4 && (m.x[1] - 1.0).abs() < 1e-4, "{m:?}");
    }

    #[test]
    fn is_deterministic_and_survives_nan() {
        let f =
            |x: &[f64]| if x[0] < -3.0 { f64::NAN } else { (x[0] - 2.0).powi(2) + (x[1] + 1.0).powi(2) + x[2].abs() };
        let a = minimize(f, &[0.0, 0.0, 1.0], &[1.0, 1.0, 1.0], Options::default());
        let b = minimize(f, &[0.0, 0.0, 1.0], &[1.0, 1.0, 1.0], Options::default());
        assert_eq!(a, b);
        assert!(a.value < 1e-6, "{a:?}");
    }
}
