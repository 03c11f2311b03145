//! The number formats of every report and table: the CSVs of `hvs experiment`, `RESULTS.md`,
//! `POSTURE.md`, `hvs demo` and `hvs eval`. One definition each, so the same value reads the
//! same everywhere.

/// A CSV number: 6 decimals (`-0` prints as `0`), `nan`, or `inf` for either infinity (a
/// method without an estimate).
pub fn num(v: f64) -> String {
    if v.is_finite() {
        format!("{:.6}", v + 0.0)
    } else if v.is_nan() {
        "nan".to_string()
    } else {
        "inf".to_string()
    }
}

/// A percentage without its unit, about four significant digits: 1 decimal from 100, 2 from
/// 10, 3 below; `inf` for a method that failed somewhere, `-` for no value (NaN).
pub fn pct_value(v: f64) -> String {
    if v.is_nan() {
        "-".to_string()
    } else if !v.is_finite() {
        "inf".to_string()
    } else if v.abs() >= 100.0 {
        format!("{v:.1}")
    } else if v.abs() >= 10.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.3}")
    }
}

/// A percentage for the text and tables: [`pct_value`] and ` %` (none after `inf` or `-`).
pub fn pct(v: f64) -> String {
    if v.is_finite() {
        format!("{} %", pct_value(v))
    } else {
        pct_value(v)
    }
}

/// A ratio to the floor: 2 decimals and ` x`.
pub fn times(v: f64) -> String {
    format!("{v:.2} x")
}

/// Values joined by `sep`, each by its `Display` (`65, 85, 165` for depths in cm).
pub fn join<T: std::fmt::Display>(v: impl IntoIterator<Item = T>, sep: &str) -> String {
    v.into_iter().map(|x| x.to_string()).collect::<Vec<_>>().join(sep)
}

/// Stage times as `name 1.2, name 3.4` (seconds, 1 decimal).
pub fn stages(stage_s: &[(&str, f64)]) -> String {
    join(stage_s.iter().map(|(n, v)| format!("{n} {v:.1}")), ", ")
}

/// Roman numerals of the thesis' cases 1-4 (`?` outside).
pub fn roman(case: u8) -> &'static str {
    match case {
        1 => "I",
        2 => "II",
        3 => "III",
        4 => "IV",
        _ => "?",
    }
}

/// The smallest and largest of `v` (`(inf, -inf)` when empty).
pub fn span(v: impl IntoIterator<Item = f64>) -> (f64, f64) {
    v.into_iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| (lo.min(x), hi.max(x)))
}

/// The mean of `v` (NaN when empty).
pub fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// A value as given in a message: shortest round-trip digits, in exponent form when very
/// large or small (`1e30`, not thirty-one digits).
pub fn given(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-4..1e7).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// `n` and `noun` (`"restart"`), `s` added unless `n` is 1: `1 restart`, `10 restarts`.
pub fn count(n: usize, noun: &str) -> String {
    format!("{n} {noun}{}", if n == 1 { "" } else { "s" })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn given_values() {
        assert_eq!(given(1e30), "1e30");
        assert_eq!(given(-2.5e-9), "-2.5e-9");
        assert_eq!(given(356.25), "356.25");
        assert_eq!(given(200000.0), "200000");
        assert_eq!(given(0.0), "0");
    }

    #[test]
    fn csv_numbers() {
        assert_eq!(num(1.0 / 3.0), "0.333333");
        assert_eq!(num(-0.0), "0.000000");
        assert_eq!(num(-1e-9), "-0.000000");
        assert_eq!(num(f64::INFINITY), "inf");
        assert_eq!(num(f64::NEG_INFINITY), "inf");
        assert_eq!(num(f64::NAN), "nan");
    }

    #[test]
    fn percentages_keep_about_four_digits() {
        assert_eq!(pct(0.017387), "0.017 %");
        assert_eq!(pct(3.99649), "3.996 %");
        assert_eq!(pct(15.9712), "15.97 %");
        assert_eq!(pct(1259.14), "1259.1 %");
        assert_eq!(pct(-12.345), "-12.35 %");
        assert_eq!(pct(f64::INFINITY), "inf");
        assert_eq!(pct(f64::NAN), "-");
        assert_eq!(pct_value(4.3456), "4.346");
    }

    #[test]
    fn small_helpers() {
        assert_eq!(times(1.234), "1.23 x");
        assert_eq!(join([65.0, 85.0, 105.5], ", "), "65, 85, 105.5");
        assert_eq!(stages(&[("a", 1.26), ("b", 0.0)]), "a 1.3, b 0.0");
        assert_eq!((roman(1), roman(4), roman(5)), ("I", "IV", "?"));
        assert_eq!(span([3.0, -1.0, 2.0]), (-1.0, 3.0));
        assert_eq!(mean(&[1.0, 2.0, 6.0]), 3.0);
        assert!(mean(&[]).is_nan());
    }
}
