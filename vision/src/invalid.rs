//! The "parameter out of range" error that [`crate::matching`] and [`crate::render`] share,
//! and the range checks that produce it; and the reading of fixed-length lists in the JSON
//! descriptions (boards, scenes).

use std::fmt;

/// Largest length or coordinate (cm) any description takes: a scene's positions and sizes, a
/// board's square, a capture's placement (1 km). Past it a value is a typo or garbage, and the
/// geometry downstream would fail with a message that hides the cause.
pub const MAX_CM: f64 = 1.0e5;

/// Smallest board square (cm): a tenth of a millimetre, finer than any printed board.
pub const MIN_SQUARE_CM: f64 = 0.01;

/// A parameter or input is out of its range: which one, and what is wrong with it.
#[derive(Debug, Clone, PartialEq)]
pub struct InvalidField {
    /// The parameter (e.g. `params.half_window`, `board.square_cm`).
    pub field: &'static str,
    /// What is wrong with it.
    pub reason: String,
}

impl InvalidField {
    /// The error for `field`.
    pub fn new(field: &'static str, reason: impl Into<String>) -> Self {
        InvalidField { field, reason: reason.into() }
    }
}

impl fmt::Display for InvalidField {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.field, self.reason)
    }
}

impl std::error::Error for InvalidField {}

/// `N` numbers in brackets, or an error that says how many were given (serde's own for an
/// array of fixed length reads past the last one as "trailing characters"): serde's
/// `deserialize_with` for the lists of `BOARD.json` and of the scene files.
pub(crate) fn numbers<'de, D, T, const N: usize>(d: D) -> Result<[T; N], D::Error>
where
    D: serde::Deserializer<'de>,
    T: serde::Deserialize<'de> + Copy,
{
    let v = <Vec<T> as serde::Deserialize>::deserialize(d)?;
    <[T; N]>::try_from(v.as_slice()).map_err(|_| {
        serde::de::Error::custom(format!("expected {N} numbers in brackets, got {}", v.len()))
    })
}

/// `value` must lie in `lo..=hi` ("must be from lo to hi, got value").
pub(crate) fn in_range<T: PartialOrd + fmt::Display>(
    field: &'static str,
    value: T,
    lo: T,
    hi: T,
) -> Result<(), InvalidField> {
    if value < lo || value > hi {
        return Err(InvalidField::new(field, format!("must be from {lo} to {hi}, got {value}")));
    }
    Ok(())
}

/// `value` must be finite and in `lo..=hi` ("must be a number from lo to hi, got value").
pub(crate) fn finite_in(
    field: &'static str,
    value: f64,
    lo: f64,
    hi: f64,
) -> Result<(), InvalidField> {
    if !(value.is_finite() && (lo..=hi).contains(&value)) {
        return Err(InvalidField::new(
            field,
            format!("must be a number from {lo} to {hi}, got {value}"),
        ));
    }
    Ok(())
}

/// Asserts that `result` is an error whose message starts with `field`.
#[cfg(test)]
#[track_caller]
pub(crate) fn assert_refused<T: fmt::Debug, E: fmt::Display>(result: Result<T, E>, field: &str) {
    match result {
        Ok(v) => panic!("accepted, expected an error naming {field}: {v:?}"),
        Err(e) => {
            let e = e.to_string();
            assert!(e.starts_with(field), "{e:?} does not start with {field}");
        }
    }
}

/// The two images of a pair must be the same size ("right: image is WxH, the left one WxH").
pub(crate) fn same_size(
    left: &image::GrayImage,
    right: &image::GrayImage,
) -> Result<(), InvalidField> {
    if left.dimensions() != right.dimensions() {
        let (lw, lh, rw, rh) = (left.width(), left.height(), right.width(), right.height());
        let why = format!("image is {rw}x{rh}, the left one {lw}x{lh}: both must be the same size");
        return Err(InvalidField::new("right", why));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_pair_of_two_sizes_is_refused_naming_both() {
        let (a, b) = (image::GrayImage::new(4, 3), image::GrayImage::new(5, 3));
        assert!(super::same_size(&a, &a.clone()).is_ok());
        let e = super::same_size(&a, &b).unwrap_err().to_string();
        assert_eq!(e, "right: image is 5x3, the left one 4x3: both must be the same size");
    }
}
