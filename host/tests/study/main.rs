//! Tests of the study library (`hvs_host::study`) through its public API, one module per
//! study.

mod posture;
