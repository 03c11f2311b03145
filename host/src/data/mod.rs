//! Files in and out: the in-memory data set, CSV point sets, rig JSON, model files, and the one
//! atomic writer (temporary file in the target directory, renamed into place when complete).

pub mod captures;
pub mod csv;
pub mod dataset;
pub mod model;
pub mod output;
pub mod pixels;
pub mod positions;
pub mod rig;
pub mod validate;
