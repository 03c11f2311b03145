//! Report prose lives in `host/templates/*.md`, compiled in with `include_str!`; the numbers
//! in it are placeholders such as `{case2_phi_l}`, filled from computed values by [`fill`].
//! `{{` and `}}` stand for literal braces.

use anyhow::{bail, Result};

/// Fills the placeholders of `template` (named `name` in errors) with `values`.
///
/// Errors on a placeholder without a value, on a value no placeholder uses, on a value given
/// twice, and on an unclosed `{` or a lone `}`: a template and the code that fills it cannot
/// drift apart silently.
pub fn fill(name: &str, template: &str, values: &[(&str, String)]) -> Result<String> {
    for (k, (key, _)) in values.iter().enumerate() {
        if values[..k].iter().any(|(other, _)| other == key) {
            bail!("template {name}: value {{{key}}} given twice");
        }
    }
    let mut used = vec![false; values.len()];
    let mut out = String::with_capacity(template.len() + 64 * values.len());
    let mut rest = template;
    while let Some(k) = rest.find(['{', '}']) {
        out.push_str(&rest[..k]);
        let line = 1 + template[..template.len() - rest.len() + k].matches('\n').count();
        let tail = &rest[k..];
        if tail.starts_with("{{") || tail.starts_with("}}") {
            out.push_str(&tail[..1]);
            rest = &tail[2..];
            continue;
        }
        if tail.starts_with('}') {
            bail!("template {name}, line {line}: a lone `}}` (write `}}}}`)");
        }
        let Some(end) = tail.find('}') else {
            bail!("template {name}, line {line}: `{{` is never closed");
        };
        let key = &tail[1..end];
        if key.is_empty() || !key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            bail!("template {name}, line {line}: `{{{key}}}` is not a placeholder name");
        }
        let Some(i) = values.iter().position(|(k, _)| *k == key) else {
            bail!("template {name}, line {line}: no value for {{{key}}}");
        };
        used[i] = true;
        out.push_str(&values[i].1);
        rest = &tail[end + 1..];
    }
    out.push_str(rest);
    if let Some(i) = used.iter().position(|u| !u) {
        bail!("template {name}: value {{{}}} is not in the template", values[i].0);
    }
    Ok(out)
}
