//! `hvs view`: a local web page over the libraries the CLI uses. [`session`] loads the model
//! and the pictures and runs the page's actions through the same functions as `hvs locate`,
//! `hvs board detect` and `hvs train`; [`frames`] is where pictures come from (still files
//! now; a live source implements the same trait); [`api`] is the JSON; `server` the
//! HTTP layer; `assets` the embedded page.

pub mod api;
mod assets;
pub mod frames;
mod server;
pub mod session;

pub use server::{needs_token, random_token, serve, MAX_BODY};
pub use session::{RetrainOptions, Session, Source};
