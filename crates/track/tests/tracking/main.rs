//! Integration tests of the tracker on rendered sequences and real recordings.

mod accuracy;
mod common;
mod crossing;
mod scenes;
mod styles;
mod debug;
