//! `hvs view`: a local web page over the libraries the CLI uses. [`session`] loads the model
//! and the pictures and runs the page's actions through the same functions as `hvs locate`,
//! `hvs depth`, `hvs board detect`, `hvs train` and `hvs track`; [`frames`] is where pictures
//! come from (the [`frames::PairStore`] trait; still files), [`live`] the virtual head in the
//! loop on the wall clock (`--scene`); [`api`] is the JSON; `server` the HTTP layer; `assets`
//! the embedded page.

pub mod api;
mod assets;
pub mod frames;
pub mod live;
mod server;
pub mod session;

pub use server::{needs_token, random_token, serve, MAX_BODY};
pub use session::{RetrainOptions, Session, Source};
