// Research oracle code included by acc_research.rs (gold-standard projective fits).
use nalgebra::{DMatrix, DVector, Matrix3x4, Vector4};

/// Reprojection of `p` through `m`.
pub fn proj(m: &Matrix3x4<f64>, p: &[f64; 3]) -> Option<[f64; 2]> {
    let h = m * Vector4::new(p[0], p[1], p[2], 1.0);
    (h[2].abs() > 1e-300).then(|| [h[0] / h[2], h[1] / h[2]])
}

/// Sum of squared reprojection residuals.
pub fn sse(m: &Matrix3x4<f64>, pts: &[[f64; 3]], px: &[[f64; 2]]) -> f64 {
    pts.iter()
        .zip(px)
        .map(|(p, x)| match proj(m, p) {
            Some(q) => (q[0] - x[0]).powi(2) + (q[1] - x[1]).powi(2),
            None => f64::INFINITY,
        })
        .sum()
}

/// LM refinement of a 3x4 P on the reprojection error (gold standard), scale fixed by unit norm.
pub fn refine(m0: &Matrix3x4<f64>, pts: &[[f64; 3]], px: &[[f64; 2]]) -> Matrix3x4<f64> {
    let mut m = *m0 / m0.norm();
    let mut cost = sse(&m, pts, px);
    let mut lambda = 1e-3;
    let n = pts.len();
    for _ in 0..200 {
        let mut j = DMatrix::<f64>::zeros(2 * n, 12);
        let mut r = DVector::<f64>::zeros(2 * n);
        for (i, (p, x)) in pts.iter().zip(px).enumerate() {
            let xh = [p[0], p[1], p[2], 1.0];
            let h = m * Vector4::new(p[0], p[1], p[2], 1.0);
            let w = h[2];
            let (u, v) = (h[0] / w, h[1] / w);
            r[2 * i] = u - x[0];
            r[2 * i + 1] = v - x[1];
            for k in 0..4 {
                j[(2 * i, k)] = xh[k] / w;
                j[(2 * i, 8 + k)] = -u * xh[k] / w;
                j[(2 * i + 1, 4 + k)] = xh[k] / w;
                j[(2 * i + 1, 8 + k)] = -v * xh[k] / w;
            }
        }
        let jtj = j.transpose() * &j;
        let jtr = j.transpose() * &r;
        let mut improved = false;
        for _ in 0..20 {
            let mut a = jtj.clone();
            for q in 0..12 {
                a[(q, q)] += lambda * (jtj[(q, q)] + 1e-12);
            }
            let Some(dp) = a.lu().solve(&(-&jtr)) else {
                lambda *= 10.0;
                continue;
            };
            let mut t = m;
            for q in 0..12 {
                t[(q / 4, q % 4)] += dp[q];
            }
            let t = t / t.norm();
            let c = sse(&t, pts, px);
            if c < cost {
                let rel = (cost - c) / cost.max(1e-300);
                m = t;
                cost = c;
                lambda = (lambda * 0.1).max(1e-12);
                improved = rel > 1e-14;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    m
}

/// Linear triangulation with rows `(u p3 - p1) / w_c` (w = 1: plain algebraic, unit rows
/// when `norm`).
pub fn tri_lin(
    p: &[Matrix3x4<f64>; 2],
    px: &[f64; 4],
    w: [f64; 2],
    norm: bool,
) -> Option<[f64; 3]> {
    let mut a = nalgebra::Matrix4::<f64>::zeros();
    for (c, m) in p.iter().enumerate() {
        let (u, v) = (px[2 * c], px[2 * c + 1]);
        let eq0 = m.row(2) * u - m.row(0);
        let eq1 = m.row(2) * v - m.row(1);
        for (k, eq) in [eq0, eq1].iter().enumerate() {
            let s = if norm { eq.norm() } else { w[c] };
            for jj in 0..4 {
                a[(2 * c + k, jj)] = eq[jj] / s;
            }
        }
    }
    let svd = a.svd(false, true);
    let vt = svd.v_t?;
    let (imin, _) = svd
        .singular_values
        .iter()
        .enumerate()
        .fold(
            (0, f64::INFINITY),
            |m, (i, s)| if *s < m.1 { (i, *s) } else { m },
        );
    let x: Vector4<f64> = vt.row(imin).transpose();
    (x[3].abs() > 1e-300).then(|| [x[0] / x[3], x[1] / x[3], x[2] / x[3]])
}

/// Depth-like weights `p3 . X` of a point in both cameras.
pub fn depths(p: &[Matrix3x4<f64>; 2], x: &[f64; 3]) -> [f64; 2] {
    core::array::from_fn(|c| (p[c] * Vector4::new(x[0], x[1], x[2], 1.0))[2])
}

/// Linear triangulation with `k` reweighting steps (Hartley-Sturm iterative linear).
pub fn tri_rw(p: &[Matrix3x4<f64>; 2], px: &[f64; 4], k: usize) -> Option<[f64; 3]> {
    // Start: rows scaled so that the third row of each P has unit norm on its first 3 entries.
    let s: [f64; 2] = core::array::from_fn(|c| {
        let r = p[c].row(2);
        (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt()
    });
    let mut x = tri_lin(p, px, s, false)?;
    for _ in 0..k {
        let w = depths(p, &x);
        x = tri_lin(p, px, w, false)?;
    }
    Some(x)
}

/// Optimal triangulation with fitted P's: Gauss-Newton on the four reprojection residuals.
pub fn tri_opt(p: &[Matrix3x4<f64>; 2], px: &[f64; 4]) -> Option<[f64; 3]> {
    let mut x = tri_rw(p, px, 1)?;
    let cost = |x: &[f64; 3]| -> f64 {
        let mut s = 0.0;
        for c in 0..2 {
            match proj(&p[c], x) {
                Some(q) => s += (q[0] - px[2 * c]).powi(2) + (q[1] - px[2 * c + 1]).powi(2),
                None => return f64::INFINITY,
            }
        }
        s
    };
    let mut cur = cost(&x);
    for _ in 0..50 {
        let mut jtj = [[0.0f64; 3]; 3];
        let mut jtr = [0.0f64; 3];
        for c in 0..2 {
            let m = &p[c];
            let h = m * Vector4::new(x[0], x[1], x[2], 1.0);
            let w = h[2];
            let q = [h[0] / w, h[1] / w];
            for row in 0..2 {
                let jr: [f64; 3] = core::array::from_fn(|a| (m[(row, a)] - q[row] * m[(2, a)]) / w);
                let r = q[row] - px[2 * c + row];
                for a in 0..3 {
                    jtr[a] += jr[a] * r;
                    for b in 0..3 {
                        jtj[a][b] += jr[a] * jr[b];
                    }
                }
            }
        }
        let dp = hvs_shared::sim::triangulate::solve3(&jtj, &[-jtr[0], -jtr[1], -jtr[2]])?;
        let t = [x[0] + dp[0], x[1] + dp[1], x[2] + dp[2]];
        let c = cost(&t);
        if c > cur {
            break;
        }
        x = t;
        let small = dp.iter().map(|v| v * v).sum::<f64>() < 1e-20;
        cur = c;
        if small {
            break;
        }
    }
    Some(x)
}

/// A constrained pinhole camera: `x ~ K R (X - C)`, `K = [f·a s cx; 0 f cy; 0 0 1]`.
#[derive(Clone, Copy, Debug)]
pub struct Pin {
    /// Focal length (px).
    pub f: f64,
    /// Aspect ratio (f_u / f_v).
    pub aspect: f64,
    /// Skew.
    pub skew: f64,
    /// Principal point.
    pub c: [f64; 2],
    /// Rotation.
    pub r: nalgebra::Rotation3<f64>,
    /// Camera centre.
    pub centre: [f64; 3],
}

impl Pin {
    /// As a 3x4 matrix.
    pub fn matrix(&self) -> Matrix3x4<f64> {
        let k = nalgebra::Matrix3::new(
            self.f * self.aspect,
            self.skew,
            self.c[0],
            0.0,
            self.f,
            self.c[1],
            0.0,
            0.0,
            1.0,
        );
        let m = k * self.r.matrix();
        let t = -(m * nalgebra::Vector3::new(self.centre[0], self.centre[1], self.centre[2]));
        let mut p = Matrix3x4::zeros();
        p.fixed_view_mut::<3, 3>(0, 0).copy_from(&m);
        p.set_column(3, &t);
        p
    }

    /// Decomposes a 3x4 P (RQ of its left 3x3).
    pub fn from_matrix(p: &Matrix3x4<f64>) -> Pin {
        let mut p = *p;
        let m: nalgebra::Matrix3<f64> = p.fixed_view::<3, 3>(0, 0).into();
        if m.determinant() < 0.0 {
            p = -p;
        }
        let m: nalgebra::Matrix3<f64> = p.fixed_view::<3, 3>(0, 0).into();
        let flip = nalgebra::Matrix3::new(0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0);
        let qr = (flip * m).transpose().qr();
        let (q, u) = (qr.q(), qr.r());
        let mut k = flip * u.transpose() * flip;
        let mut r = flip * q.transpose();
        // Positive diagonal of K.
        for i in 0..3 {
            if k[(i, i)] < 0.0 {
                for row in 0..3 {
                    k[(row, i)] = -k[(row, i)];
                }
                for col in 0..3 {
                    r[(i, col)] = -r[(i, col)];
                }
            }
        }
        let s = k[(2, 2)];
        let k = k / s;
        let c = -(m.try_inverse().unwrap() * p.column(3));
        Pin {
            f: k[(1, 1)],
            aspect: k[(0, 0)] / k[(1, 1)],
            skew: k[(0, 1)],
            c: [k[(0, 2)], k[(1, 2)]],
            r: nalgebra::Rotation3::from_matrix(&r),
            centre: [c[0], c[1], c[2]],
        }
    }
}

/// Which intrinsics are free in [`refine_pin`].
#[derive(Clone, Copy, Debug)]
pub struct Free {
    /// Principal point free.
    pub c: bool,
    /// Aspect free.
    pub aspect: bool,
    /// Skew free.
    pub skew: bool,
}

fn apply(p0: &Pin, free: Free, d: &[f64]) -> Pin {
    let mut p = *p0;
    let mut k = 0;
    p.f += d[k];
    k += 1;
    let w = nalgebra::Vector3::new(d[k], d[k + 1], d[k + 2]);
    p.r = nalgebra::Rotation3::from_scaled_axis(w) * p.r;
    k += 3;
    for i in 0..3 {
        p.centre[i] += d[k + i];
    }
    k += 3;
    if free.c {
        p.c[0] += d[k];
        p.c[1] += d[k + 1];
        k += 2;
    }
    if free.aspect {
        p.aspect += d[k];
        k += 1;
    }
    if free.skew {
        p.skew += d[k];
    }
    p
}

fn n_free(free: Free) -> usize {
    7 + 2 * free.c as usize + free.aspect as usize + free.skew as usize
}

/// LM (numeric Jacobian) of a constrained camera on the reprojection error.
pub fn refine_pin(p0: &Pin, free: Free, pts: &[[f64; 3]], px: &[[f64; 2]]) -> Pin {
    let np = n_free(free);
    let n = pts.len();
    let res = |p: &Pin| -> DVector<f64> {
        let m = p.matrix();
        let mut r = DVector::zeros(2 * n);
        for (i, (q, x)) in pts.iter().zip(px).enumerate() {
            let y = proj(&m, q).unwrap_or([1e9, 1e9]);
            r[2 * i] = y[0] - x[0];
            r[2 * i + 1] = y[1] - x[1];
        }
        r
    };
    let mut p = *p0;
    let mut r = res(&p);
    let mut cost = r.norm_squared();
    let mut lambda = 1e-3;
    let steps: [f64; 11] = [
        1e-4, 1e-7, 1e-7, 1e-7, 1e-5, 1e-5, 1e-5, 1e-5, 1e-5, 1e-5, 1e-5,
    ];
    for _ in 0..200 {
        let mut j = DMatrix::<f64>::zeros(2 * n, np);
        for q in 0..np {
            let h = if q == 0 {
                1e-4
            } else {
                steps[q.min(steps.len() - 1)].max(1e-7)
            };
            let mut d = vec![0.0; np];
            d[q] = h;
            let rp = res(&apply(&p, free, &d));
            d[q] = -h;
            let rm = res(&apply(&p, free, &d));
            j.set_column(q, &((rp - rm) / (2.0 * h)));
        }
        let jtj = j.transpose() * &j;
        let jtr = j.transpose() * &r;
        let mut improved = false;
        for _ in 0..20 {
            let mut a = jtj.clone();
            for q in 0..np {
                a[(q, q)] += lambda * (jtj[(q, q)] + 1e-12);
            }
            let Some(dp) = a.lu().solve(&(-&jtr)) else {
                lambda *= 10.0;
                continue;
            };
            let t = apply(&p, free, dp.as_slice());
            let rt = res(&t);
            let c = rt.norm_squared();
            if c < cost {
                let rel = (cost - c) / cost.max(1e-300);
                p = t;
                r = rt;
                cost = c;
                lambda = (lambda * 0.1).max(1e-12);
                improved = rel > 1e-13;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    p
}

/// Sum of |r|^p over all residual coordinates.
pub fn lp_cost(m: &Matrix3x4<f64>, pts: &[[f64; 3]], px: &[[f64; 2]], p: f64) -> f64 {
    pts.iter()
        .zip(px)
        .map(|(q, x)| match proj(m, q) {
            Some(y) => (y[0] - x[0]).abs().powf(p) + (y[1] - x[1]).abs().powf(p),
            None => f64::INFINITY,
        })
        .sum()
}

/// Lp fit of a 3x4 P (IRLS + damping), continuation in p from 2 up to `p_max`.
pub fn refine_lp(
    m0: &Matrix3x4<f64>,
    pts: &[[f64; 3]],
    px: &[[f64; 2]],
    p_max: f64,
) -> Matrix3x4<f64> {
    let mut m = refine(m0, pts, px);
    let n = pts.len();
    let mut p = 2.0;
    while p < p_max {
        p = (p * 2.0).min(p_max);
        let mut cost = lp_cost(&m, pts, px, p);
        let mut lambda = 1e-3;
        for _ in 0..300 {
            let mut j = DMatrix::<f64>::zeros(2 * n, 12);
            let mut r = DVector::<f64>::zeros(2 * n);
            let mut w = DVector::<f64>::zeros(2 * n);
            for (i, (q, x)) in pts.iter().zip(px).enumerate() {
                let xh = [q[0], q[1], q[2], 1.0];
                let h = m * Vector4::new(q[0], q[1], q[2], 1.0);
                let ww = h[2];
                let (u, v) = (h[0] / ww, h[1] / ww);
                r[2 * i] = u - x[0];
                r[2 * i + 1] = v - x[1];
                for k in 0..4 {
                    j[(2 * i, k)] = xh[k] / ww;
                    j[(2 * i, 8 + k)] = -u * xh[k] / ww;
                    j[(2 * i + 1, 4 + k)] = xh[k] / ww;
                    j[(2 * i + 1, 8 + k)] = -v * xh[k] / ww;
                }
            }
            for i in 0..2 * n {
                w[i] = r[i].abs().max(1e-6).powf(p - 2.0);
            }
            let wj = DMatrix::from_fn(2 * n, 12, |a, b| j[(a, b)] * w[a]);
            let jtj = j.transpose() * &wj;
            let jtr = wj.transpose() * &r;
            let mut improved = false;
            for _ in 0..30 {
                let mut a = jtj.clone();
                for q in 0..12 {
                    a[(q, q)] += lambda * (jtj[(q, q)] + 1e-12);
                }
                let Some(dp) = a.lu().solve(&(-&jtr)) else {
                    lambda *= 10.0;
                    continue;
                };
                let mut t = m;
                for q in 0..12 {
                    t[(q / 4, q % 4)] += dp[q];
                }
                let t = t / t.norm();
                let c = lp_cost(&t, pts, px, p);
                if c < cost {
                    let rel = (cost - c) / cost.max(1e-300);
                    m = t;
                    cost = c;
                    lambda = (lambda * 0.3).max(1e-12);
                    improved = rel > 1e-12;
                    break;
                }
                lambda *= 10.0;
            }
            if !improved {
                break;
            }
        }
    }
    m
}

/// Largest |residual| coordinate.
pub fn max_res(m: &Matrix3x4<f64>, pts: &[[f64; 3]], px: &[[f64; 2]]) -> f64 {
    pts.iter()
        .zip(px)
        .map(|(q, x)| {
            let y = proj(m, q).unwrap_or([f64::INFINITY; 2]);
            (y[0] - x[0]).abs().max((y[1] - x[1]).abs())
        })
        .fold(0.0, f64::max)
}
