//! The page: HTML, JavaScript and CSS compiled into the binary (no build step, nothing fetched
//! at run time; the page loads nothing from other hosts).

/// `/`.
pub const INDEX_HTML: &str = include_str!("page/index.html");
/// `/app.js`.
pub const APP_JS: &str = include_str!("page/app.js");
/// `/style.css`.
pub const STYLE_CSS: &str = include_str!("page/style.css");
