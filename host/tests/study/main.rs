//! Tests of the studies' library modules (`hvs_host::study`) through their public API, one
//! module per study.

mod accuracy;
mod engine;
mod posture;
mod template;
mod thesis;
