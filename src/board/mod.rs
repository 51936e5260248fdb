//! The board room: everything that runs on the acquisition board, `no_std`, allocation-free
//! and panic-free, and imports nothing of the host.
//!
//! The host reads this room (to run the same arithmetic in `unlag compensate`, and to write
//! the images the board parses), never the reverse. Its four parts, re-exported at the crate
//! root under the same names:
//! - [`compensator`]: the f32 cascade, run per ADC sample (with the nonlinear-damping
//!   correction and the per-temperature bank);
//! - [`fixed`]: the same cascade in 32-bit integers, normal form and direct form, for boards
//!   without an FPU;
//! - [`blob`]: the binary coefficient image a running board parses to update its set;
//! - [`process`]: the compensators as `dsp_process` processors, composing with `idsp`.
//!
//! Every error type here is one style: `core::error::Error`, a hand-written `Display` (the
//! board has no derive for it; `thiserror` is a host dependency), and `defmt::Format` derived
//! behind the `defmt` feature.

pub mod blob;
pub mod compensator;
pub mod fixed;
pub mod process;
