//! The page `hvs view` serves, in the binary: plain HTML, JavaScript and CSS (no CDN, no
//! build step).

/// `/`.
pub const INDEX_HTML: &str = include_str!("assets/index.html");
/// `/app.js`.
pub const APP_JS: &str = include_str!("assets/app.js");
/// `/style.css`.
pub const STYLE_CSS: &str = include_str!("assets/style.css");
