//! The sparse Taylor stepping's two inner loops ([`super::run`]): one
//! term of the series over the chain's rows, and the sum of a term into
//! the states inside a block step. Each is compiled twice, for the
//! baseline x86-64 (two `f64` lanes) and with AVX2 (four), and the second
//! runs where the processor has it: the same additions and multiplications
//! in the same order (no fused multiply-add), so the results are the same
//! to the bit either way; only their speed differs.

/// The tridiagonal rows of `M^-1 (-K x - D v)` and the state of one Taylor
/// term, windowed to the rows worked on (`1..=hi` of the padded vectors:
/// `tx`, `tv` hold `hi + 2` entries from row 0, the others `hi` from row 1).
pub(super) struct Term<'a> {
    pub lo: &'a [f64],
    pub dg: &'a [f64],
    pub up: &'a [f64],
    pub dd: &'a [f64],
    pub tx: &'a [f64],
    pub tv: &'a [f64],
    pub nx: &'a mut [f64],
    pub nv: &'a mut [f64],
    pub x: &'a mut [f64],
    pub v: &'a mut [f64],
}

/// The next term `alpha A t` into `nx`, `nv`, added to `x`, `v`; returns
/// its largest entry.
#[inline]
pub(super) fn term(alpha: f64, a: Term<'_>) -> f64 {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the processor has AVX2 (detected just above).
        return unsafe { term_avx2(alpha, a) };
    }
    term_body(alpha, a)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn term_avx2(alpha: f64, a: Term<'_>) -> f64 {
    term_body(alpha, a)
}

#[inline(always)]
fn term_body(alpha: f64, a: Term<'_>) -> f64 {
    let hi = a.lo.len();
    let (tx, tv) = (&a.tx[..hi + 2], &a.tv[..hi + 2]);
    let (nx, nv) = (&mut a.nx[..hi], &mut a.nv[..hi]);
    let (x, v) = (&mut a.x[..hi], &mut a.v[..hi]);
    let (dg, up, dd) = (&a.dg[..hi], &a.up[..hi], &a.dd[..hi]);
    for i in 0..hi {
        let acc =
            alpha * (a.lo[i] * tx[i] + dg[i] * tx[i + 1] + up[i] * tx[i + 2] + dd[i] * tv[i + 1]);
        let vel = alpha * tv[i + 1];
        nv[i] = acc;
        nx[i] = vel;
        v[i] += acc;
        x[i] += vel;
    }
    max_abs(nv, nx)
}

/// `between` (rows of `entries.len()` values, one per internal step `i =
/// 1..b-1` inside a block step of `b`) plus `(i / b)^m entries` for the
/// `m`-th term: `pw[i - 1]` holds `(i / b)^(m - 1)` and is raised here by
/// `ratio[i - 1] = i / b` (divided once per block step, not per term).
#[inline]
pub(super) fn accumulate(between: &mut [f64], pw: &mut [f64], ratio: &[f64], entries: &[f64]) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the processor has AVX2 (detected just above).
        return unsafe { accumulate_avx2(between, pw, ratio, entries) };
    }
    accumulate_body(between, pw, ratio, entries)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn accumulate_avx2(between: &mut [f64], pw: &mut [f64], ratio: &[f64], entries: &[f64]) {
    accumulate_body(between, pw, ratio, entries)
}

#[inline(always)]
fn accumulate_body(between: &mut [f64], pw: &mut [f64], ratio: &[f64], entries: &[f64]) {
    for (f, r) in pw.iter_mut().zip(ratio) {
        *f *= r;
    }
    for (row, f) in between.chunks_mut(entries.len()).zip(pw.iter()) {
        for (r, e) in row.iter_mut().zip(entries) {
            *r += *f * e;
        }
    }
}

/// The largest `|v|` of `a` and `b` (NaN ignored, 0 for none), in four
/// independent lanes: a single running maximum waits on each comparison
/// (half the stepping's time when it did), the lanes do not; the result is
/// the same.
#[inline(always)]
pub(super) fn max_abs(a: &[f64], b: &[f64]) -> f64 {
    let mut m = [0.0f64; 4];
    for s in [a, b] {
        let mut it = s.chunks_exact(4);
        for c in &mut it {
            for (l, &v) in m.iter_mut().zip(c) {
                let v = v.abs();
                if v > *l {
                    *l = v;
                }
            }
        }
        for &v in it.remainder() {
            let v = v.abs();
            if v > m[0] {
                m[0] = v;
            }
        }
    }
    m.into_iter().fold(0.0, |a, v| if v > a { v } else { a })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The dispatched loops (AVX2 where the processor has it) give the
    /// baseline loops' values to the bit, over lengths that leave every
    /// remainder of the vector width.
    #[test]
    fn dispatched_loops_equal_the_baseline_to_the_bit() {
        let val = |i: usize, s: f64| ((i as f64 * 0.7 + s).sin() * 1e3).powi(3) * 1e-7;
        for hi in [1usize, 2, 3, 4, 5, 7, 8, 9, 31, 64, 301] {
            let mk = |s: f64, len: usize| (0..len).map(|i| val(i, s)).collect::<Vec<f64>>();
            let (lo, dg, up, dd) = (mk(0.1, hi), mk(0.2, hi), mk(0.3, hi), mk(0.4, hi));
            let (tx, tv) = (mk(0.5, hi + 2), mk(0.6, hi + 2));
            let run = |dispatch: bool| {
                let (mut nx, mut nv) = (vec![0.0; hi], vec![0.0; hi]);
                let (mut x, mut v) = (mk(0.7, hi), mk(0.8, hi));
                let t = Term {
                    lo: &lo,
                    dg: &dg,
                    up: &up,
                    dd: &dd,
                    tx: &tx,
                    tv: &tv,
                    nx: &mut nx,
                    nv: &mut nv,
                    x: &mut x,
                    v: &mut v,
                };
                let big = if dispatch {
                    term(0.37, t)
                } else {
                    term_body(0.37, t)
                };
                (big, nx, nv, x, v)
            };
            let (a, b) = (run(true), run(false));
            assert_eq!(a.0.to_bits(), b.0.to_bits(), "hi = {hi}");
            for (p, q) in [(&a.1, &b.1), (&a.2, &b.2), (&a.3, &b.3), (&a.4, &b.4)] {
                assert!(p
                    .iter()
                    .zip(q.iter())
                    .all(|(u, w)| u.to_bits() == w.to_bits()));
            }
            let m = a.1.iter().chain(&a.2).fold(0.0f64, |m, v| m.max(v.abs()));
            assert_eq!(a.0, m, "hi = {hi}: the largest entry");
            // accumulate: b - 1 rows of w = hi entries
            for b in [2usize, 3, 5] {
                let acc = |dispatch: bool| {
                    let mut between = mk(0.9, (b - 1) * hi);
                    let mut pw = vec![1.0; b - 1];
                    let ratio: Vec<f64> = (1..b).map(|i| i as f64 / b as f64).collect();
                    for _ in 0..3 {
                        if dispatch {
                            accumulate(&mut between, &mut pw, &ratio, &tx[..hi]);
                        } else {
                            accumulate_body(&mut between, &mut pw, &ratio, &tx[..hi]);
                        }
                    }
                    between
                };
                let (p, q) = (acc(true), acc(false));
                assert!(p.iter().zip(&q).all(|(u, w)| u.to_bits() == w.to_bits()));
            }
        }
    }
}
