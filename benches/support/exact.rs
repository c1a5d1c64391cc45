//! A cheap residual for testing and tuning the optimizers before the
//! library's misfit exists: exact-model data X_1*(s_i) of a true chain at
//! fixed quadrature nodes, and
//!
//! `r(candidate) = sum_i w_i |X_1(s_i; candidate) - X_1*(s_i)|^2`,
//!
//! with the uniform chain's Green's entries tabled per node and the Woodbury
//! correction for the candidate's mass defects. Shared by `tests/search.rs`
//! and `benches/table1.rs` (included with `#[path]`).
#![allow(dead_code)]

use springmass::detect::search::{Candidate, Objective, Space};
use springmass::forward::response;
use springmass::green::Green;
use springmass::{Chain, Defect};

/// Gauss-Legendre nodes and weights on [-1, 1] (Newton on P_m).
pub fn gauss_legendre(m: usize) -> (Vec<f64>, Vec<f64>) {
    let mut x = vec![0.0; m];
    let mut w = vec![0.0; m];
    for i in 0..m {
        let mut z = (std::f64::consts::PI * (i as f64 + 0.75) / (m as f64 + 0.5)).cos();
        let mut dp = 0.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, z);
            for k in 2..=m {
                let p2 = ((2 * k - 1) as f64 * z * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = m as f64 * (z * p1 - p0) / (z * z - 1.0);
            let dz = p1 / dp;
            z -= dz;
            if dz.abs() < 1e-16 {
                break;
            }
        }
        x[i] = z;
        w[i] = 2.0 / ((1.0 - z * z) * dp * dp);
    }
    (x, w)
}

/// Composite Gauss-Legendre, `per_panel` nodes on each panel between
/// consecutive `breaks`.
pub fn composite_rule(breaks: &[f64], per_panel: usize) -> Vec<(f64, f64)> {
    let (x, w) = gauss_legendre(per_panel);
    let mut out = Vec::new();
    for p in breaks.windows(2) {
        let (a, b) = (p[0], p[1]);
        for (xi, wi) in x.iter().zip(&w) {
            out.push((0.5 * (a + b) + 0.5 * (b - a) * xi, 0.5 * (b - a) * wi));
        }
    }
    out
}

/// 80 nodes: 8-point Gauss-Legendre on 10 log-graded panels of [0, 300].
pub fn default_rule() -> Vec<(f64, f64)> {
    composite_rule(
        &[0.0, 0.1, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 20.0, 60.0, 300.0],
        8,
    )
}

/// Exact-data residual over unknown positions and masses.
pub struct ExactObjective {
    space: Space,
    n: usize,
    gamma: f64,
    s2: Vec<f64>,
    w: Vec<f64>,
    g11: Vec<f64>,
    /// node-major: `g1[i * n + (j - 1)] = G_1j(s_i)`
    g1: Vec<f64>,
    /// node-major: `gjj[i * n * n + (a - 1) * n + (b - 1)] = G_ab(s_i)`
    gjj: Vec<f64>,
    data: Vec<f64>,
}

impl ExactObjective {
    /// Data from `truth` (mass defects only), `k` unknown defects with masses
    /// in `bounds` on the uniform chain of `truth` (`mass = 1`).
    pub fn new(truth: &Chain, k: usize, bounds: (f64, f64), rule: &[(f64, f64)]) -> ExactObjective {
        let data = rule
            .iter()
            .map(|&(s, _)| response(truth, s, 1).expect("valid s"))
            .collect();
        Self::with_data(truth, k, bounds, rule, data)
    }

    /// As [`ExactObjective::new`] with given observed data `X_1*(s_i)`, one per node.
    pub fn with_data(
        truth: &Chain,
        k: usize,
        bounds: (f64, f64),
        rule: &[(f64, f64)],
        data: Vec<f64>,
    ) -> ExactObjective {
        assert_eq!(data.len(), rule.len());
        let n = truth.n();
        let mut o = ExactObjective {
            space: Space::masses(n, k, bounds),
            n,
            gamma: truth.gamma(),
            s2: Vec::new(),
            w: Vec::new(),
            g11: Vec::new(),
            g1: Vec::new(),
            gjj: Vec::new(),
            data,
        };
        for &(s, w) in rule {
            let g = Green::new(n, truth.k(), truth.mass(), truth.d(), s);
            o.s2.push(s * s);
            o.w.push(w);
            o.g11.push(g.entry(1, 1));
            for j in 1..=n {
                o.g1.push(g.entry(1, j));
            }
            for a in 1..=n {
                for b in 1..=n {
                    o.gjj.push(g.entry(a, b));
                }
            }
        }
        o
    }

    /// The paper's pipeline: simulate `x_1(t)` on `[0, t_end]` with step `dt`
    /// (library simulator), Laplace-transform the samples (library Filon-type
    /// transform, envelope tail bound) at the nodes. Returns the data and the
    /// largest relative error estimate over the nodes.
    pub fn pipeline_data(
        truth: &Chain,
        rule: &[(f64, f64)],
        t_end: f64,
        dt: f64,
    ) -> (Vec<f64>, f64) {
        use springmass::time::series::{SeriesTransform, TransformOptions};
        use springmass::time::simulate::{simulate, SimOptions};
        use springmass::Complex64;
        let traj = simulate(truth, &SimOptions::new(t_end, dt)).expect("simulation");
        let x = traj.x(1).expect("x_1 observed");
        let tr =
            SeriesTransform::uniform(0.0, dt, x, &TransformOptions::default()).expect("transform");
        let mut worst: f64 = 0.0;
        let data = rule
            .iter()
            .map(|&(s, _)| {
                let v = tr.eval(Complex64::new(s, 0.0)).expect("transform at s");
                worst = worst.max(v.err / v.value.re.abs());
                v.value.re
            })
            .collect();
        (data, worst)
    }

    /// The paper's Table 1 system `i` (1..=4): (n, [(j1, m1), (j2, m2)]).
    pub fn table1_system(i: usize) -> (usize, [(usize, f64); 2]) {
        match i {
            1 => (5, [(2, 3.0), (4, 0.5)]),
            2 => (10, [(3, 3.0), (7, 2.0)]),
            3 => (20, [(8, 5.0), (15, 2.0)]),
            _ => (20, [(8, 5.0), (15, 15.0)]),
        }
    }

    /// The chain of a Table 1 system (k = 1, d = 0.1).
    pub fn table1_chain(i: usize) -> Chain {
        let (n, d) = Self::table1_system(i);
        Chain::paper(n)
            .unwrap()
            .with_defects(d.iter().map(|&(at, m)| Defect::Mass { at, m }))
            .unwrap()
    }

    /// Predicted X_1 at node `i`.
    #[inline]
    pub fn predict(&self, i: usize, c: &Candidate) -> f64 {
        let n = self.n;
        let s2 = self.s2[i];
        let g1 = &self.g1[i * n..(i + 1) * n];
        let gjj = &self.gjj[i * n * n..(i + 1) * n * n];
        let x = match c.positions.len() {
            0 => self.g11[i],
            1 => {
                let a = c.positions[0] - 1;
                let ca = (c.values[0] - 1.0) * s2;
                let z = g1[a] / (1.0 + gjj[a * n + a] * ca);
                self.g11[i] - g1[a] * ca * z
            }
            2 => {
                let (a, b) = (c.positions[0] - 1, c.positions[1] - 1);
                let ca = (c.values[0] - 1.0) * s2;
                let cb = (c.values[1] - 1.0) * s2;
                let gab = gjj[a * n + b];
                let a00 = 1.0 + gjj[a * n + a] * ca;
                let a01 = gab * cb;
                let a10 = gab * ca;
                let a11 = 1.0 + gjj[b * n + b] * cb;
                let det = a00 * a11 - a01 * a10;
                let za = (g1[a] * a11 - a01 * g1[b]) / det;
                let zb = (a00 * g1[b] - a10 * g1[a]) / det;
                self.g11[i] - g1[a] * ca * za - g1[b] * cb * zb
            }
            k => {
                // general k: dense Gaussian elimination without pivoting
                // (I + G_JJ C is diagonally dominant enough for masses > 0)
                let mut m = vec![0.0; k * (k + 1)];
                for r in 0..k {
                    let pr = c.positions[r] - 1;
                    for q in 0..k {
                        let pq = c.positions[q] - 1;
                        let cq = (c.values[q] - 1.0) * s2;
                        m[r * (k + 1) + q] = gjj[pr * n + pq] * cq + if r == q { 1.0 } else { 0.0 };
                    }
                    m[r * (k + 1) + k] = g1[pr];
                }
                for p in 0..k {
                    for r in p + 1..k {
                        let f = m[r * (k + 1) + p] / m[p * (k + 1) + p];
                        for q in p..=k {
                            m[r * (k + 1) + q] -= f * m[p * (k + 1) + q];
                        }
                    }
                }
                let mut z = vec![0.0; k];
                for p in (0..k).rev() {
                    let mut acc = m[p * (k + 1) + k];
                    for q in p + 1..k {
                        acc -= m[p * (k + 1) + q] * z[q];
                    }
                    z[p] = acc / m[p * (k + 1) + p];
                }
                let mut x = self.g11[i];
                for ((&pl, &ml), zl) in c.positions.iter().zip(&c.values).zip(&z) {
                    x -= g1[pl - 1] * (ml - 1.0) * s2 * zl;
                }
                x
            }
        };
        self.gamma * x
    }
}

impl Objective for ExactObjective {
    fn space(&self) -> &Space {
        &self.space
    }
    fn cost(&self, c: &Candidate) -> f64 {
        if !self.space.contains(c) {
            return 1e10;
        }
        let mut r = 0.0;
        for i in 0..self.w.len() {
            let e = self.predict(i, c) - self.data[i];
            r += self.w[i] * e * e;
        }
        if r.is_finite() {
            r
        } else {
            1e10
        }
    }
}
