//! The modelling loop's diagnosis: which physical effect a model misses on its tests, ranked,
//! with the change that adds it.
//!
//! It reads beside the data's flow: [`crate::evidence`] measures the residual on each test,
//! [`diagnose`] ranks the candidate effects from that evidence and a trial refit of each, and
//! [`crate::effects`] holds the effects and their fits. The pipeline's fit reaches the effects
//! directly, never through this room.

pub mod diagnose;
