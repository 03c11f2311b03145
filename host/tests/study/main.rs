//! Tests of the studies' library modules (`hvs_host::study`) through their public API, one
//! module per study.

mod posture;
