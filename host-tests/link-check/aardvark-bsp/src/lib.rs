//! A stand-in board-support crate: it only gives the firmware its memory map (`build.rs`).
#![no_std]
