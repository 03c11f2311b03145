//! Report templates: placeholders filled, and every way a template and its values can disagree.

use hvs_host::study::template::fill;

fn v(pairs: &[(&'static str, &str)]) -> Vec<(&'static str, String)> {
    pairs.iter().map(|(k, x)| (*k, x.to_string())).collect()
}

#[test]
fn fills_every_placeholder_and_unescapes_braces() {
    let s = fill(
        "t",
        "case II: {phi_l} vs. {phi_r} px, {phi_l} again; {{literal}}\n",
        &v(&[("phi_l", "285.8"), ("phi_r", "406.9")]),
    )
    .unwrap();
    assert_eq!(s, "case II: 285.8 vs. 406.9 px, 285.8 again; {literal}\n");
    assert_eq!(fill("t", "no placeholders", &[]).unwrap(), "no placeholders");
}

#[test]
fn a_placeholder_without_a_value_is_an_error() {
    let e = fill("results.md", "a\n{x} {y}", &v(&[("x", "1")])).unwrap_err().to_string();
    assert_eq!(e, "template results.md, line 2: no value for {y}");
}

#[test]
fn a_value_without_a_placeholder_is_an_error() {
    let e = fill("t", "{x}", &v(&[("x", "1"), ("z", "2")])).unwrap_err().to_string();
    assert_eq!(e, "template t: value {z} is not in the template");
    let e = fill("t", "{x}", &v(&[("x", "1"), ("x", "2")])).unwrap_err().to_string();
    assert_eq!(e, "template t: value {x} given twice");
}

#[test]
fn malformed_braces_are_errors() {
    for (t, want) in [
        ("{x", "`{` is never closed"),
        ("x}", "a lone `}`"),
        ("{a b}", "`{a b}` is not a placeholder name"),
        ("{}", "`{}` is not a placeholder name"),
    ] {
        let e = fill("t", t, &v(&[("x", "1")])).unwrap_err().to_string();
        assert!(e.contains(want), "{t}: {e}");
    }
}
