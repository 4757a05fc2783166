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

/// Result of a minimisation in `N` dimensions.
#[derive(Clone, Debug, PartialEq)]
pub struct Minimum<const N: usize> {
    /// Argument of the best value.
    pub x: [f64; N],
    /// Best value (non-finite values are treated as +∞).
    pub value: f64,
    /// Function evaluations used.
    pub evals: usize,
}

/// Minimises `f` from `x0` with initial simplex steps `step` (one per coordinate). Points are
/// arrays: a BSPVT bake runs millions of short two-dimensional minimisations.
pub fn minimize<const N: usize>(
    mut f: impl FnMut(&[f64; N]) -> f64,
    x0: [f64; N],
    step: [f64; N],
    opts: Options,
) -> Minimum<N> {
    let mut eval = |x: &[f64; N]| {
        let v = f(x);
        if v.is_nan() { f64::INFINITY } else { v }
    };
    let mut best = Minimum { x: x0, value: eval(&x0), evals: 1 };
    for _ in 0..=opts.restarts {
        let (x, value, evals) = one_start(&mut eval, best.x, step, opts);
        best.evals += evals;
        if value <= best.value {
            best.x = x;
            best.value = value;
        }
    }
    best
}

/// `a + t (b − a)` per coordinate.
fn lerp<const N: usize>(a: &[f64; N], b: &[f64; N], t: f64) -> [f64; N] {
    std::array::from_fn(|k| a[k] + t * (b[k] - a[k]))
}

/// Sorts simplex vertices by value, stably (as `sort_by` would): an insertion sort in place,
/// since N + 1 is a handful and the library's out-of-line small sort cost a call per step.
fn sort_by_value<const N: usize>(simplex: &mut [([f64; N], f64)]) {
    for i in 1..simplex.len() {
        let mut j = i;
        while j > 0 && simplex[j - 1].1.total_cmp(&simplex[j].1).is_gt() {
            simplex.swap(j - 1, j);
            j -= 1;
        }
    }
}

fn one_start<const N: usize>(
    f: &mut impl FnMut(&[f64; N]) -> f64,
    x0: [f64; N],
    step: [f64; N],
    opts: Options,
) -> ([f64; N], f64, usize) {
    // N + 1 vertices; a Vec, as `[_; N + 1]` is not yet expressible.
    let mut simplex: Vec<([f64; N], f64)> = Vec::with_capacity(N + 1);
    simplex.push((x0, f(&x0)));
    for i in 0..N {
        let mut x = x0;
        x[i] += step[i];
        simplex.push((x, f(&x)));
    }
    let mut evals = N + 1;
    while evals < opts.max_evals {
        sort_by_value(&mut simplex);
        if (simplex[N].1 - simplex[0].1).abs() <= opts.tolerance * (1.0 + simplex[0].1.abs()) {
            break;
        }
        let centroid: [f64; N] = std::array::from_fn(|k| simplex[..N].iter().map(|s| s.0[k]).sum::<f64>() / N as f64);
        let worst = simplex[N].1;
        let reflected = lerp(&centroid, &simplex[N].0, -1.0);
        let fr = f(&reflected);
        evals += 1;
        simplex[N] = if fr < simplex[0].1 {
            let expanded = lerp(&centroid, &simplex[N].0, -2.0);
            let fe = f(&expanded);
            evals += 1;
            if fe < fr { (expanded, fe) } else { (reflected, fr) }
        } else if fr < simplex[N - 1].1 {
            (reflected, fr)
        } else {
            let (towards, fw) = if fr < worst { (reflected, fr) } else { simplex[N] };
            let contracted = lerp(&centroid, &towards, 0.5);
            let fc = f(&contracted);
            evals += 1;
            if fc >= fw {
                let best = simplex[0].0;
                for s in &mut simplex[1..] {
                    s.0 = std::array::from_fn(|k| best[k] + 0.5 * (s.0[k] - best[k]));
                    s.1 = f(&s.0);
                }
                evals += N;
                continue;
            }
            (contracted, fc)
        };
    }
    sort_by_value(&mut simplex);
    (simplex[0].0, simplex[0].1, evals)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_rosenbrock_minimum() {
        let rosen = |x: &[f64; 2]| (1.0 - x[0]).powi(2) + 100.0 * (x[1] - x[0] * x[0]).powi(2);
        let m = minimize(rosen, [-1.2, 1.0], [0.5, 0.5], Options { max_evals: 5000, ..Default::default() });
        assert!((m.x[0] - 1.0).abs() < 1e-4 && (m.x[1] - 1.0).abs() < 1e-4, "{m:?}");
    }

    #[test]
    fn is_deterministic_and_survives_nan() {
        let f = |x: &[f64; 3]| {
            if x[0] < -3.0 { f64::NAN } else { (x[0] - 2.0).powi(2) + (x[1] + 1.0).powi(2) + x[2].abs() }
        };
        let a = minimize(f, [0.0, 0.0, 1.0], [1.0, 1.0, 1.0], Options::default());
        let b = minimize(f, [0.0, 0.0, 1.0], [1.0, 1.0, 1.0], Options::default());
        assert_eq!(a, b);
        assert!(a.value < 1e-6, "{a:?}");
    }
}
