//! Projective geometry on pixel coordinates: homographies (normalised DLT), the camera
//! projection matrix (normalised DLT) with linear triangulation, and the fundamental matrix
//! (normalised 8-point, rank 2, then Levenberg-Marquardt on the Sampson error).
//!
//! Pixel coordinates follow the crate convention: `(u, v)` continuous, integer values at pixel
//! centres (pixel (0, 0)'s centre is (0, 0)), `u` to the right, `v` downwards. Nothing here
//! depends on that convention except the units of the residuals (pixels).
//!
//! The fundamental matrix `F` relates a left point `l` and a right point `r` of the same scene
//! point by `r~^T F l~ = 0` (`~`: homogeneous `[u, v, 1]`): `F l~` is the epipolar line of `l` in
//! the right image.

use hvs_shared::sim::camera::Camera;
use nalgebra::{DMatrix, Matrix3, Matrix3x4, Matrix4, Vector3, Vector4};

/// A 3x3 matrix, rows first.
pub type Mat3 = [[f64; 3]; 3];

/// Why a geometric fit failed.
#[derive(Debug, Clone, PartialEq)]
pub enum GeomError {
    /// Fewer point pairs than the model needs.
    TooFewPoints {
        /// Pairs the fit needs at least.
        need: usize,
        /// Pairs given.
        got: usize,
    },
    /// A coordinate is NaN or infinite (index of the first bad pair).
    NonFinite {
        /// Index of the pair.
        index: usize,
    },
    /// The points do not determine the model (coincident, collinear, or, for `F`, a plane
    /// seen by both cameras or too few distinct points).
    Degenerate(&'static str),
}

impl core::fmt::Display for GeomError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            GeomError::TooFewPoints { need, got } => {
                write!(f, "too few point pairs: need at least {need}, got {got}")
            }
            GeomError::NonFinite { index } => {
                write!(f, "point pair {index} has a non-finite coordinate")
            }
            GeomError::Degenerate(why) => write!(f, "degenerate point configuration: {why}"),
        }
    }
}

impl std::error::Error for GeomError {}

fn to_na(m: &Mat3) -> Matrix3<f64> {
    Matrix3::new(m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2], m[2][0], m[2][1], m[2][2])
}

fn from_na(m: &Matrix3<f64>) -> Mat3 {
    [
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
    ]
}

fn mul3(m: &Mat3, p: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * p[0] + m[0][1] * p[1] + m[0][2] * p[2],
        m[1][0] * p[0] + m[1][1] * p[1] + m[1][2] * p[2],
        m[2][0] * p[0] + m[2][1] * p[1] + m[2][2] * p[2],
    ]
}

fn mul3t(m: &Mat3, p: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * p[0] + m[1][0] * p[1] + m[2][0] * p[2],
        m[0][1] * p[0] + m[1][1] * p[1] + m[2][1] * p[2],
        m[0][2] * p[0] + m[1][2] * p[1] + m[2][2] * p[2],
    ]
}

/// Scale a matrix to unit Frobenius norm with a positive largest-magnitude entry (a canonical
/// representative of the projective class).
fn canonical(m: &Matrix3<f64>) -> Matrix3<f64> {
    let n = m.norm();
    let mut big = 0.0f64;
    for v in m.iter() {
        if v.abs() > big.abs() {
            big = *v;
        }
    }
    let s = if big < 0.0 { -1.0 } else { 1.0 };
    m * (s / n)
}

/// Hartley normalisation: the similarity moving the points' centroid to the origin and their
/// mean distance to it to `sqrt(2)`. `None` when all points coincide.
fn normaliser(pts: impl Iterator<Item = [f64; 2]> + Clone) -> Option<Matrix3<f64>> {
    let n = pts.clone().count() as f64;
    let (mut cx, mut cy) = (0.0, 0.0);
    for p in pts.clone() {
        cx += p[0];
        cy += p[1];
    }
    cx /= n;
    cy /= n;
    let mut d = 0.0;
    for p in pts {
        d += ((p[0] - cx).powi(2) + (p[1] - cy).powi(2)).sqrt();
    }
    d /= n;
    if d.partial_cmp(&(1e-12 * (1.0 + cx.abs() + cy.abs()))) != Some(core::cmp::Ordering::Greater) {
        return None;
    }
    let s = core::f64::consts::SQRT_2 / d;
    Some(Matrix3::new(s, 0.0, -s * cx, 0.0, s, -s * cy, 0.0, 0.0, 1.0))
}

fn apply_na(t: &Matrix3<f64>, p: [f64; 2]) -> [f64; 2] {
    let q = t * Vector3::new(p[0], p[1], 1.0);
    [q[0] / q[2], q[1] / q[2]]
}

fn check_finite(pairs: &[([f64; 2], [f64; 2])]) -> Result<(), GeomError> {
    for (index, (a, b)) in pairs.iter().enumerate() {
        if !(a[0].is_finite() && a[1].is_finite() && b[0].is_finite() && b[1].is_finite()) {
            return Err(GeomError::NonFinite { index });
        }
    }
    Ok(())
}

/// The checks and the normalisations of a DLT on `pairs`: at least `need` pairs, all finite,
/// and for each side the [`normaliser`] of its points (`coincide[side]` is the error when
/// that side's points all coincide).
fn pair_normalisers(
    pairs: &[([f64; 2], [f64; 2])],
    need: usize,
    coincide: [&'static str; 2],
) -> Result<[Matrix3<f64>; 2], GeomError> {
    if pairs.len() < need {
        return Err(GeomError::TooFewPoints { need, got: pairs.len() });
    }
    check_finite(pairs)?;
    let first = normaliser(pairs.iter().map(|p| p.0)).ok_or(GeomError::Degenerate(coincide[0]))?;
    let second = normaliser(pairs.iter().map(|p| p.1)).ok_or(GeomError::Degenerate(coincide[1]))?;
    Ok([first, second])
}

/// The right singular vector of the smallest singular value of `a` (rows padded with zeros to
/// at least as many as columns, so the full right basis exists), with the singular values in
/// ascending order.
fn null_vector(mut a: DMatrix<f64>) -> (Vec<f64>, Vec<f64>) {
    let cols = a.ncols();
    if a.nrows() < cols {
        let rows = a.nrows();
        a = a.insert_rows(rows, cols - rows, 0.0);
    }
    let svd = a.svd(false, true);
    let v_t = svd.v_t.expect("v_t was requested");
    let sv = svd.singular_values;
    let mut order: Vec<usize> = (0..sv.len()).collect();
    order.sort_by(|&i, &j| sv[i].total_cmp(&sv[j]));
    let k = order[0];
    let v = (0..cols).map(|c| v_t[(k, c)]).collect();
    let sorted = order.iter().map(|&i| sv[i]).collect();
    (v, sorted)
}

/// A plane-to-image (or image-to-image) homography: `p' ~ H [x, y, 1]^T`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Homography {
    /// The matrix, rows first, unit Frobenius norm.
    pub m: Mat3,
}

impl Homography {
    /// The image of `p`, or `None` when it maps to infinity.
    pub fn apply(&self, p: [f64; 2]) -> Option<[f64; 2]> {
        let q = mul3(&self.m, [p[0], p[1], 1.0]);
        if q[2].abs() < 1e-300 {
            return None;
        }
        let out = [q[0] / q[2], q[1] / q[2]];
        (out[0].is_finite() && out[1].is_finite()).then_some(out)
    }
}

/// A homography fit and how well it fits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HomographyFit {
    /// The fitted homography, source -> destination.
    pub h: Homography,
    /// Root mean square of the destination-side distances `|H src - dst|` (units of `dst`).
    pub rms: f64,
    /// Largest of those distances.
    pub max: f64,
}

/// Fit `dst ~ H src` to `pairs = [(src, dst), ...]` (at least 4, no three of the first four
/// collinear) by the normalised direct linear transform (Hartley & Zisserman, alg. 4.2).
pub fn fit_homography(pairs: &[([f64; 2], [f64; 2])]) -> Result<HomographyFit, GeomError> {
    let [ts, td] = pair_normalisers(
        pairs,
        4,
        ["all source points coincide", "all destination points coincide"],
    )?;
    let mut a = DMatrix::<f64>::zeros(2 * pairs.len(), 9);
    for (k, (s, d)) in pairs.iter().enumerate() {
        let [x, y] = apply_na(&ts, *s);
        let [u, v] = apply_na(&td, *d);
        let r0 = [0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v];
        let r1 = [x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y, -u];
        for c in 0..9 {
            a[(2 * k, c)] = r0[c];
            a[(2 * k + 1, c)] = r1[c];
        }
    }
    let (h, sv) = null_vector(a);
    if sv[1] <= 1e-10 * sv[8] {
        return Err(GeomError::Degenerate("the points do not determine a homography (collinear?)"));
    }
    let hn = Matrix3::from_row_slice(&h);
    let td_inv = td.try_inverse().ok_or(GeomError::Degenerate("normalisation not invertible"))?;
    let hm = canonical(&(td_inv * hn * ts));
    let h = Homography { m: from_na(&hm) };
    let mut sum = 0.0;
    let mut max = 0.0f64;
    for (s, d) in pairs {
        let p = h.apply(*s).ok_or(GeomError::Degenerate(
            "a source point maps to infinity under the fitted homography",
        ))?;
        let e2 = (p[0] - d[0]).powi(2) + (p[1] - d[1]).powi(2);
        sum += e2;
        max = max.max(e2.sqrt());
    }
    Ok(HomographyFit { h, rms: (sum / pairs.len() as f64).sqrt(), max })
}

/// A 3x4 camera projection matrix: `p~ ~ P [X, Y, Z, 1]^T`.
pub type Projection = Matrix3x4<f64>;

/// A 3x4 projection matrix fitted by the normalised DLT (Hartley & Zisserman, alg. 7.1) to
/// world points and their pixels (at least 6, not all on one plane).
pub fn fit_dlt(points: &[[f64; 3]], pixels: &[[f64; 2]]) -> Result<Projection, GeomError> {
    let n = points.len();
    if n < 6 || pixels.len() != n {
        return Err(GeomError::TooFewPoints { need: 6, got: n.min(pixels.len()) });
    }
    // Similarity normalisations: centroid to 0, mean distance sqrt(3) (3-D) and sqrt(2) (2-D).
    let c3 = points.iter().fold([0.0; 3], |a, p| [a[0] + p[0], a[1] + p[1], a[2] + p[2]]);
    let c3 = c3.map(|v| v / n as f64);
    let d3 = points
        .iter()
        .map(|p| {
            let d = [p[0] - c3[0], p[1] - c3[1], p[2] - c3[2]];
            (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
        })
        .sum::<f64>()
        / n as f64;
    let s3 = 3f64.sqrt() / d3;
    let c2 = pixels.iter().fold([0.0; 2], |a, p| [a[0] + p[0], a[1] + p[1]]);
    let c2 = c2.map(|v| v / n as f64);
    let d2 = pixels
        .iter()
        .map(|p| ((p[0] - c2[0]).powi(2) + (p[1] - c2[1]).powi(2)).sqrt())
        .sum::<f64>()
        / n as f64;
    let s2 = 2f64.sqrt() / d2;
    let mut a = DMatrix::<f64>::zeros(2 * n, 12);
    for (r, (p, x)) in points.iter().zip(pixels).enumerate() {
        let pw = [(p[0] - c3[0]) * s3, (p[1] - c3[1]) * s3, (p[2] - c3[2]) * s3, 1.0];
        let (u, v) = ((x[0] - c2[0]) * s2, (x[1] - c2[1]) * s2);
        for k in 0..4 {
            a[(2 * r, k)] = pw[k];
            a[(2 * r, 8 + k)] = -u * pw[k];
            a[(2 * r + 1, 4 + k)] = pw[k];
            a[(2 * r + 1, 8 + k)] = -v * pw[k];
        }
    }
    let svd = a.svd(false, true);
    let vt = svd.v_t.ok_or(GeomError::Degenerate("the SVD gave no right singular vectors"))?;
    let imin = smallest(svd.singular_values.iter());
    let h = vt.row(imin);
    let pn = Matrix3x4::from_fn(|r, c| h[4 * r + c]);
    let t2 = Matrix3::new(s2, 0.0, -s2 * c2[0], 0.0, s2, -s2 * c2[1], 0.0, 0.0, 1.0);
    let t3 = Matrix4::new(
        s3,
        0.0,
        0.0,
        -s3 * c3[0],
        0.0,
        s3,
        0.0,
        -s3 * c3[1],
        0.0,
        0.0,
        s3,
        -s3 * c3[2],
        0.0,
        0.0,
        0.0,
        1.0,
    );
    let t2i = t2.try_inverse().ok_or(GeomError::Degenerate("all pixels coincide"))?;
    Ok(t2i * pn * t3)
}

/// Index of the smallest of `values` (the first, on ties; 0 when empty or all NaN): the
/// singular vector a homogeneous least-squares problem takes.
fn smallest<'a>(values: impl Iterator<Item = &'a f64>) -> usize {
    values.enumerate().fold((0, f64::INFINITY), |m, (i, s)| if *s < m.1 { (i, *s) } else { m }).0
}

/// Linear (DLT) triangulation of one point from two projection matrices and its pixels
/// `[u_l, v_l, u_r, v_r]`; `None` when the point is at infinity or not finite.
pub fn triangulate_dlt(p: &[Projection; 2], px: &[f64; 4]) -> Option<[f64; 3]> {
    let mut a = Matrix4::<f64>::zeros();
    for (c, m) in p.iter().enumerate() {
        let (u, v) = (px[2 * c], px[2 * c + 1]);
        let r0 = m.row(0);
        let r1 = m.row(1);
        let r2 = m.row(2);
        let eq0 = r2 * u - r0;
        let eq1 = r2 * v - r1;
        for (k, eq) in [eq0, eq1].iter().enumerate() {
            let nrm = eq.norm();
            for j in 0..4 {
                a[(2 * c + k, j)] = eq[j] / nrm;
            }
        }
    }
    let svd = a.svd(false, true);
    let vt = svd.v_t?;
    let imin = smallest(svd.singular_values.iter());
    let x: Vector4<f64> = vt.row(imin).transpose();
    if x[3].abs() < 1e-300 {
        return None;
    }
    let p3 = Vector3::new(x[0] / x[3], x[1] / x[3], x[2] / x[3]);
    p3.iter().all(|v| v.is_finite()).then(|| [p3[0], p3[1], p3[2]])
}

/// A fundamental matrix: `r~^T m l~ = 0` for a left point `l` and right point `r` of one scene
/// point. Rank 2, unit Frobenius norm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fundamental {
    /// The matrix, rows first.
    pub m: Mat3,
}

/// Divide a line `[a, b, c]` by `sqrt(a^2 + b^2)`, so `a u + b v + c` is a signed distance in
/// pixels. A degenerate line (`a = b = 0`) is returned unchanged.
fn unit_line(l: [f64; 3]) -> [f64; 3] {
    let n = (l[0] * l[0] + l[1] * l[1]).sqrt();
    if n > 0.0 {
        [l[0] / n, l[1] / n, l[2] / n]
    } else {
        l
    }
}

impl Fundamental {
    /// The epipolar line of left point `ul` in the right image, `[a, b, c]` with
    /// `a^2 + b^2 = 1`: the right points `(u, v)` with `a u + b v + c = 0`, and `a u + b v + c`
    /// is a point's signed distance from it in pixels.
    pub fn line_in_right(&self, ul: [f64; 2]) -> [f64; 3] {
        unit_line(mul3(&self.m, [ul[0], ul[1], 1.0]))
    }

    /// The epipolar line of right point `ur` in the left image, normalised like
    /// [`Fundamental::line_in_right`].
    pub fn line_in_left(&self, ur: [f64; 2]) -> [f64; 3] {
        unit_line(mul3t(&self.m, [ur[0], ur[1], 1.0]))
    }

    /// Distance (px) of right point `r` from the epipolar line of left point `l`.
    pub fn distance_in_right(&self, l: [f64; 2], r: [f64; 2]) -> f64 {
        let line = self.line_in_right(l);
        (line[0] * r[0] + line[1] * r[1] + line[2]).abs()
    }

    /// Distance (px) of left point `l` from the epipolar line of right point `r`.
    pub fn distance_in_left(&self, l: [f64; 2], r: [f64; 2]) -> f64 {
        let line = self.line_in_left(r);
        (line[0] * l[0] + line[1] * l[1] + line[2]).abs()
    }

    /// Symmetric epipolar distance (px): `sqrt((d_r^2 + d_l^2) / 2)` of the two point-to-line
    /// distances above.
    pub fn symmetric(&self, l: [f64; 2], r: [f64; 2]) -> f64 {
        let a = self.distance_in_right(l, r);
        let b = self.distance_in_left(l, r);
        ((a * a + b * b) / 2.0).sqrt()
    }

    /// Signed Sampson error (px): the first-order distance of `(u_l, v_l, u_r, v_r)` from the
    /// nearest pair that satisfies the epipolar constraint exactly (moving both points). For
    /// small errors it is about `sqrt(2)` times each image's share of the correction.
    pub fn sampson_signed(&self, l: [f64; 2], r: [f64; 2]) -> f64 {
        let lh = [l[0], l[1], 1.0];
        let rh = [r[0], r[1], 1.0];
        let fl = mul3(&self.m, lh);
        let ftr = mul3t(&self.m, rh);
        let e = rh[0] * fl[0] + rh[1] * fl[1] + fl[2];
        let g = (fl[0] * fl[0] + fl[1] * fl[1] + ftr[0] * ftr[0] + ftr[1] * ftr[1]).sqrt();
        if g > 0.0 {
            e / g
        } else {
            0.0
        }
    }

    /// Sampson error (px), the absolute value of [`Fundamental::sampson_signed`].
    pub fn sampson(&self, l: [f64; 2], r: [f64; 2]) -> f64 {
        self.sampson_signed(l, r).abs()
    }

    /// The left and right epipoles (null vectors of `m` and `m^T`), as homogeneous 3-vectors
    /// with unit norm (last component near 0 when an epipole is at infinity).
    pub fn epipoles(&self) -> ([f64; 3], [f64; 3]) {
        let f = to_na(&self.m);
        let svd = f.svd(true, true);
        let (u, v_t) = (svd.u.expect("u"), svd.v_t.expect("v_t"));
        let k = (0..3)
            .min_by(|&i, &j| svd.singular_values[i].total_cmp(&svd.singular_values[j]))
            .unwrap_or(2);
        ([v_t[(k, 0)], v_t[(k, 1)], v_t[(k, 2)]], [u[(0, k)], u[(1, k)], u[(2, k)]])
    }
}

/// A fundamental matrix fit and its residuals over the fitted pairs.
#[derive(Debug, Clone, PartialEq)]
pub struct FundamentalFit {
    /// The refined, rank-2 fundamental matrix.
    pub f: Fundamental,
    /// RMS Sampson error over the pairs (px).
    pub rms_sampson: f64,
    /// Median distance of the right points from their left points' epipolar lines (px).
    pub median_distance_in_right: f64,
    /// Iterations of the nonlinear refinement that lowered the cost.
    pub iterations: usize,
}

/// Fit a fundamental matrix to `pairs = [(left, right), ...]` (at least 8, not all on one
/// plane): normalised 8-point algorithm on an SVD, rank 2 enforced, then Levenberg-Marquardt
/// on the Sampson error over a minimal rank-2 parametrisation (`U diag(1, s, 0) V^T`).
///
/// Every pair is used (no outlier rejection): the caller passes validated correspondences.
pub fn fit_fundamental(pairs: &[([f64; 2], [f64; 2])]) -> Result<Fundamental, GeomError> {
    fit_fundamental_report(pairs).map(|fit| fit.f)
}

/// [`fit_fundamental`] with the residual summary.
pub fn fit_fundamental_report(pairs: &[([f64; 2], [f64; 2])]) -> Result<FundamentalFit, GeomError> {
    let f0 = eight_point(pairs)?;
    let (f, iterations) = refine_sampson(&f0, pairs);
    let mut d: Vec<f64> = pairs.iter().map(|(l, r)| f.distance_in_right(*l, *r)).collect();
    d.sort_by(f64::total_cmp);
    let median =
        if d.len() % 2 == 1 { d[d.len() / 2] } else { (d[d.len() / 2 - 1] + d[d.len() / 2]) / 2.0 };
    Ok(FundamentalFit {
        rms_sampson: rms_sampson(&f, pairs),
        median_distance_in_right: median,
        f,
        iterations,
    })
}

fn rms_sampson(f: &Fundamental, pairs: &[([f64; 2], [f64; 2])]) -> f64 {
    let s: f64 = pairs.iter().map(|(l, r)| f.sampson_signed(*l, *r).powi(2)).sum();
    (s / pairs.len() as f64).sqrt()
}

/// The normalised 8-point estimate, rank 2 enforced (Hartley & Zisserman, alg. 11.1).
pub fn eight_point(pairs: &[([f64; 2], [f64; 2])]) -> Result<Fundamental, GeomError> {
    let [tl, tr] =
        pair_normalisers(pairs, 8, ["all left points coincide", "all right points coincide"])?;
    let mut a = DMatrix::<f64>::zeros(pairs.len(), 9);
    for (k, (l, r)) in pairs.iter().enumerate() {
        let [x, y] = apply_na(&tl, *l);
        let [u, v] = apply_na(&tr, *r);
        let row = [u * x, u * y, u, v * x, v * y, v, x, y, 1.0];
        for (c, val) in row.iter().enumerate() {
            a[(k, c)] = *val;
        }
    }
    let (f, sv) = null_vector(a);
    if sv[1] <= 1e-9 * sv[8] {
        return Err(GeomError::Degenerate(
            "the pairs do not determine a fundamental matrix (one plane, or too few distinct points)",
        ));
    }
    let fnorm = Matrix3::from_row_slice(&f);
    let svd = fnorm.svd(true, true);
    let (u, v_t) = (svd.u.expect("u"), svd.v_t.expect("v_t"));
    let mut s = svd.singular_values;
    // nalgebra sorts singular values in descending order.
    s[2] = 0.0;
    let f2 = u * Matrix3::from_diagonal(&s) * v_t;
    let fm = canonical(&(tr.transpose() * f2 * tl));
    Ok(Fundamental { m: from_na(&fm) })
}

/// Rotation about axis `k` by angle `t`.
fn axis_rot(k: usize, t: f64) -> Matrix3<f64> {
    let (s, c) = t.sin_cos();
    match k {
        0 => Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c),
        1 => Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c),
        _ => Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0),
    }
}

/// The orthonormal representation of a rank-2 matrix (Bartoli & Sturm): `U diag(1, s, 0) V^T`
/// with `U, V` rotations, updated by 7 increments (3 + 3 small rotations, one `s`).
#[derive(Clone, Copy)]
struct Orthonormal {
    u: Matrix3<f64>,
    v: Matrix3<f64>,
    s: f64,
}

impl Orthonormal {
    fn from(f: &Fundamental) -> Orthonormal {
        let svd = to_na(&f.m).svd(true, true);
        let mut u = svd.u.expect("u");
        let mut v = svd.v_t.expect("v_t").transpose();
        // Make both proper rotations; flipping the null column changes nothing (its singular
        // value is zero).
        if u.determinant() < 0.0 {
            u.column_mut(2).neg_mut();
        }
        if v.determinant() < 0.0 {
            v.column_mut(2).neg_mut();
        }
        let sv = svd.singular_values;
        let s = if sv[0] > 0.0 { sv[1] / sv[0] } else { 0.0 };
        Orthonormal { u, v, s }
    }

    fn matrix(&self) -> Mat3 {
        let d = Matrix3::from_diagonal(&Vector3::new(1.0, self.s, 0.0));
        from_na(&canonical(&(self.u * d * self.v.transpose())))
    }

    fn step(&self, x: &[f64; 7]) -> Orthonormal {
        let ru = axis_rot(0, x[0]) * axis_rot(1, x[1]) * axis_rot(2, x[2]);
        let rv = axis_rot(0, x[3]) * axis_rot(1, x[4]) * axis_rot(2, x[5]);
        Orthonormal { u: self.u * ru, v: self.v * rv, s: self.s + x[6] }
    }
}

fn sampson_residuals(f: &Mat3, pairs: &[([f64; 2], [f64; 2])], out: &mut [f64]) {
    let fm = Fundamental { m: *f };
    for (o, (l, r)) in out.iter_mut().zip(pairs) {
        *o = fm.sampson_signed(*l, *r);
    }
}

/// Levenberg-Marquardt on the Sampson residuals over the orthonormal representation, with a
/// central-difference Jacobian. Returns the refined matrix and the accepted iterations; never
/// worse than the start.
fn refine_sampson(f0: &Fundamental, pairs: &[([f64; 2], [f64; 2])]) -> (Fundamental, usize) {
    let n = pairs.len();
    let mut cur = Orthonormal::from(f0);
    let mut res = vec![0.0; n];
    sampson_residuals(&cur.matrix(), pairs, &mut res);
    let mut cost: f64 = res.iter().map(|r| r * r).sum();
    let mut lambda = 1e-3;
    let mut accepted = 0;
    let mut jac = vec![[0.0f64; 7]; n];
    let (mut rp, mut rm) = (vec![0.0; n], vec![0.0; n]);
    for _ in 0..50 {
        if cost == 0.0 || !cost.is_finite() {
            break;
        }
        for p in 0..7 {
            let h = if p == 6 { 1e-7 * (1.0 + cur.s) } else { 1e-7 };
            let mut dx = [0.0; 7];
            dx[p] = h;
            sampson_residuals(&cur.step(&dx).matrix(), pairs, &mut rp);
            dx[p] = -h;
            sampson_residuals(&cur.step(&dx).matrix(), pairs, &mut rm);
            for k in 0..n {
                jac[k][p] = (rp[k] - rm[k]) / (2.0 * h);
            }
        }
        let mut jtj = nalgebra::SMatrix::<f64, 7, 7>::zeros();
        let mut jtr = nalgebra::SVector::<f64, 7>::zeros();
        for k in 0..n {
            for a in 0..7 {
                jtr[a] += jac[k][a] * res[k];
                for b in 0..7 {
                    jtj[(a, b)] += jac[k][a] * jac[k][b];
                }
            }
        }
        let mut improved = false;
        for _ in 0..10 {
            let mut m = jtj;
            for a in 0..7 {
                m[(a, a)] += lambda * (jtj[(a, a)].max(1e-12));
            }
            let Some(delta) = m.cholesky().map(|c| c.solve(&(-jtr))) else {
                lambda *= 10.0;
                continue;
            };
            let dx: [f64; 7] = core::array::from_fn(|a| delta[a]);
            let cand = cur.step(&dx);
            sampson_residuals(&cand.matrix(), pairs, &mut rp);
            let c: f64 = rp.iter().map(|r| r * r).sum();
            if c.is_finite() && c < cost {
                let rel = (cost - c) / cost;
                cur = cand;
                std::mem::swap(&mut res, &mut rp);
                cost = c;
                lambda = (lambda / 10.0).max(1e-12);
                accepted += 1;
                improved = rel > 1e-12;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    let refined = Fundamental { m: cur.matrix() };
    // The refinement starts at f0 and only accepts lower costs, but keep the guarantee explicit.
    let mut r0 = vec![0.0; n];
    sampson_residuals(&f0.m, pairs, &mut r0);
    let c0: f64 = r0.iter().map(|r| r * r).sum();
    if cost <= c0 {
        (refined, accepted)
    } else {
        (*f0, 0)
    }
}

/// The fundamental matrix of two pinhole cameras (no lens): `r~^T F l~ = 0`, unit Frobenius
/// norm. For a thesis rig at home: `pinhole_fundamental(&rig.left(), &rig.right())`.
pub fn pinhole_fundamental(left: &Camera, right: &Camera) -> Fundamental {
    // Right-camera coordinates of a left ray point: R (x - c_r) with x = c_l + R_l^T y.
    let rl = left.rotation;
    let rr = right.rotation;
    // R = R_r R_l^T, t = R_r (c_l - c_r).
    let mut rot = [[0.0; 3]; 3];
    for (i, row) in rot.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = (0..3).map(|k| rr[i][k] * rl[j][k]).sum();
        }
    }
    let dc = [
        left.center[0] - right.center[0],
        left.center[1] - right.center[1],
        left.center[2] - right.center[2],
    ];
    let t: [f64; 3] = core::array::from_fn(|i| (0..3).map(|k| rr[i][k] * dc[k]).sum());
    let tx = [[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]];
    let mut e = [[0.0; 3]; 3];
    for (i, row) in e.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = (0..3).map(|k| tx[i][k] * rot[k][j]).sum();
        }
    }
    // K^-1 = [[1/fu, 0, -u0/fu], [0, 1/fv, -v0/fv], [0, 0, 1]].
    let kinv = |c: &Camera| {
        [
            [1.0 / c.phi_u, 0.0, -c.u0 / c.phi_u],
            [0.0, 1.0 / c.phi_v, -c.v0 / c.phi_v],
            [0.0, 0.0, 1.0],
        ]
    };
    let (kl, kr) = (kinv(left), kinv(right));
    // F = Kr^-T E Kl^-1.
    let mut tmp = [[0.0; 3]; 3];
    for (i, row) in tmp.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = (0..3).map(|k| e[i][k] * kl[k][j]).sum();
        }
    }
    let mut f = [[0.0; 3]; 3];
    for (i, row) in f.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = (0..3).map(|k| kr[k][i] * tmp[k][j]).sum();
        }
    }
    let norm = f.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
    if norm > 0.0 {
        f.iter_mut().flatten().for_each(|x| *x /= norm);
    }
    Fundamental { m: f }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hvs_shared::sim::camera::Rig;

    /// A verged, slightly rolled and tilted rig: a generic epipolar geometry.
    fn rig() -> Rig {
        let mut r = Rig::parallel(600.0);
        r.phi_u_right = 590.0;
        r.phi_v_left = 605.0;
        r.alpha_left = 0.05;
        r.alpha_right = -0.04;
        r.beta0 = 0.01;
        r.phi0 = 0.015;
        r.u0 = 318.5;
        r.v0 = 241.25;
        r
    }

    /// The DLT recovers a projective camera from points off one plane: a new point's exact
    /// pixels reproject and triangulate back; five points are refused.
    #[test]
    fn dlt_recovers_a_projective_camera_and_triangulates_exactly() {
        use hvs_shared::sim::posture::{joints_from_gaze, HeadRig};
        let head = HeadRig::new(rig());
        let [l, r] = head.cameras(&joints_from_gaze(10.0, -5.0, 3.0, 4.0, 6.0));
        let mut pts = Vec::new();
        for z in [60.0, 90.0, 130.0] {
            for i in 0..4 {
                for j in 0..3 {
                    pts.push([-15.0 + 10.0 * f64::from(i), -8.0 + 8.0 * f64::from(j), z]);
                }
            }
        }
        let px_l: Vec<[f64; 2]> = pts.iter().map(|p| l.project(p).unwrap()).collect();
        let px_r: Vec<[f64; 2]> = pts.iter().map(|p| r.project(p).unwrap()).collect();
        let p = [fit_dlt(&pts, &px_l).unwrap(), fit_dlt(&pts, &px_r).unwrap()];
        let q = [3.0, -2.0, 100.0];
        let want = [l.project(&q).unwrap(), r.project(&q).unwrap()];
        for c in 0..2 {
            let h = p[c] * Vector4::new(q[0], q[1], q[2], 1.0);
            assert!((h[0] / h[2] - want[c][0]).abs() < 1e-6, "{h:?} {want:?}");
            assert!((h[1] / h[2] - want[c][1]).abs() < 1e-6);
        }
        let px = [want[0][0], want[0][1], want[1][0], want[1][1]];
        let t = triangulate_dlt(&p, &px).unwrap();
        for k in 0..3 {
            assert!((t[k] - q[k]).abs() < 1e-6, "{t:?}");
        }
        assert_eq!(
            fit_dlt(&pts[..5], &px_l[..5]),
            Err(GeomError::TooFewPoints { need: 6, got: 5 })
        );
    }

    /// Scene points on three boards at different poses (non-planar overall), projected exactly.
    fn exact_pairs(rig: &Rig, offset: f64) -> Vec<([f64; 2], [f64; 2])> {
        let mut out = Vec::new();
        for (z, tilt) in [(80.0, 0.2), (120.0, -0.3), (170.0, 0.1)] {
            for j in 0..6 {
                for i in 0..9 {
                    let x = (i as f64 - 4.0) * 5.0 + offset;
                    let y = (j as f64 - 2.5) * 5.0;
                    let p = [x, y + 3.0, z + x * f64::sin(tilt)];
                    let px = rig.project(&p).unwrap();
                    out.push(([px[0], px[1]], [px[2], px[3]]));
                }
            }
        }
        out
    }

    #[test]
    fn fundamental_recovers_exact_epipolar_geometry() {
        let r = rig();
        let pairs = exact_pairs(&r, 0.0);
        let fit = fit_fundamental_report(&pairs).unwrap();
        assert!(fit.rms_sampson < 1e-9, "rms {}", fit.rms_sampson);
        // Points not used in the fit lie on the predicted lines too.
        let held_out = exact_pairs(&r, 2.5);
        for (l, rr) in &held_out {
            let d = fit.f.distance_in_right(*l, *rr);
            assert!(d < 1e-8, "held-out distance {d}");
            assert!(fit.f.distance_in_left(*l, *rr) < 1e-8);
        }
        // Rank 2.
        let det = to_na(&fit.f.m).determinant();
        assert!(det.abs() < 1e-12, "det {det}");
        // The left epipole is the right camera centre's image in the left camera.
        let (el, _) = fit.f.epipoles();
        let e = r.left().project(&[r.half_baseline, 0.0, 0.0]);
        match e {
            Some(e) => {
                assert!((el[0] / el[2] - e[0]).abs() < 1e-4 * e[0].abs().max(1.0));
                assert!((el[1] / el[2] - e[1]).abs() < 1e-4 * e[1].abs().max(1.0));
            }
            None => {
                // Behind the camera: the epipole is still the projection of the centre line.
                let c = r.left().to_camera(&[r.half_baseline, 0.0, 0.0]);
                let eu = r.left().phi_u * c[0] / c[2] + r.left().u0;
                assert!((el[0] / el[2] - eu).abs() < 1e-4 * eu.abs().max(1.0));
            }
        }
    }

    #[test]
    fn fundamental_refinement_lowers_sampson_on_noisy_points() {
        let r = rig();
        let mut pairs = exact_pairs(&r, 0.0);
        // Deterministic pseudo-noise (0.3 px scale) from a fixed LCG.
        let mut s: u64 = 12345;
        let mut next = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.6
        };
        for p in pairs.iter_mut() {
            p.0[0] += next();
            p.0[1] += next();
            p.1[0] += next();
            p.1[1] += next();
        }
        let f0 = eight_point(&pairs).unwrap();
        let fit = fit_fundamental_report(&pairs).unwrap();
        let c0 = rms_sampson(&f0, &pairs);
        assert!(fit.rms_sampson <= c0, "{} > {c0}", fit.rms_sampson);
        assert!(fit.rms_sampson < 0.3, "rms {}", fit.rms_sampson);
        // Held-out exact points stay near their lines.
        for (l, rr) in exact_pairs(&r, 2.5) {
            assert!(fit.f.distance_in_right(l, rr) < 0.5);
        }
    }

    #[test]
    fn line_in_right_passes_through_the_match_and_is_normalised() {
        let r = rig();
        let pairs = exact_pairs(&r, 0.0);
        let f = fit_fundamental(&pairs).unwrap();
        let (l, rr) = pairs[17];
        let line = f.line_in_right(l);
        assert!((line[0].hypot(line[1]) - 1.0).abs() < 1e-12);
        assert!((line[0] * rr[0] + line[1] * rr[1] + line[2]).abs() < 1e-9);
        // A point 2 px off the line along its normal is 2 px away.
        let off = [rr[0] + 2.0 * line[0], rr[1] + 2.0 * line[1]];
        assert!((f.distance_in_right(l, off) - 2.0).abs() < 1e-9);
        assert!(f.symmetric(l, rr) < 1e-9 && f.sampson(l, rr) < 1e-9);
    }

    #[test]
    fn fundamental_rejects_bad_input() {
        let r = rig();
        let pairs = exact_pairs(&r, 0.0);
        assert_eq!(fit_fundamental(&pairs[..7]), Err(GeomError::TooFewPoints { need: 8, got: 7 }));
        let mut bad = pairs.clone();
        bad[3].1[0] = f64::NAN;
        assert_eq!(fit_fundamental(&bad), Err(GeomError::NonFinite { index: 3 }));
        // One board only: a plane, degenerate for F.
        assert!(matches!(fit_fundamental(&pairs[..54]), Err(GeomError::Degenerate(_))));
        let same = vec![([1.0, 2.0], [3.0, 4.0]); 20];
        assert!(matches!(fit_fundamental(&same), Err(GeomError::Degenerate(_))));
    }

    #[test]
    fn homography_fits_exact_board_projection() {
        let r = rig();
        let cam = r.left();
        let mut pairs = Vec::new();
        for j in 0..6 {
            for i in 0..9 {
                let (x, y) = (i as f64 * 6.0, j as f64 * 6.0);
                // Board plane tilted about the vertical axis.
                let p = [x - 24.0, y - 15.0, 150.0 + 0.4 * x];
                pairs.push(([x, y], cam.project(&p).unwrap()));
            }
        }
        let fit = fit_homography(&pairs).unwrap();
        assert!(fit.rms < 1e-9 && fit.max < 1e-9, "rms {}", fit.rms);
        // An off-grid board point maps to its exact projection.
        let q = fit.h.apply([13.0, 7.0]).unwrap();
        let t = cam.project(&[13.0 - 24.0, 7.0 - 15.0, 150.0 + 0.4 * 13.0]).unwrap();
        assert!((q[0] - t[0]).abs() < 1e-9 && (q[1] - t[1]).abs() < 1e-9);
        // Residual is in destination units: shifting one point by 3 px shows up.
        pairs[10].1[0] += 3.0;
        let fit = fit_homography(&pairs).unwrap();
        assert!(fit.rms > 0.1 && fit.max > 1.0);
    }

    #[test]
    fn homography_rejects_bad_input() {
        assert_eq!(
            fit_homography(&[([0.0, 0.0], [0.0, 0.0]); 3]),
            Err(GeomError::TooFewPoints { need: 4, got: 3 })
        );
        let line: Vec<_> =
            (0..6).map(|k| ([k as f64, 2.0 * k as f64], [k as f64, k as f64])).collect();
        assert!(matches!(fit_homography(&line), Err(GeomError::Degenerate(_))));
        let mut p: Vec<_> = (0..6).map(|k| ([k as f64, (k * k) as f64], [k as f64, 1.0])).collect();
        p[2].0[1] = f64::INFINITY;
        assert_eq!(fit_homography(&p), Err(GeomError::NonFinite { index: 2 }));
    }

    #[test]
    fn pinhole_fundamental_holds_for_projected_points() {
        for n in 1..=4 {
            let rig = hvs_shared::sim::presets::case(n).unwrap();
            let f = pinhole_fundamental(&rig.left(), &rig.right());
            for p in [[-20.0, -10.0, 65.0], [15.0, 12.0, 165.0], [0.0, 0.0, 100.0]] {
                let px = rig.project(&p).unwrap();
                let d = f.distance_in_right([px[0], px[1]], [px[2], px[3]]);
                assert!(d < 1e-9, "case {n}: {d}");
            }
        }
    }
}
