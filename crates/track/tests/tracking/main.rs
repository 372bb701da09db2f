//! Integration tests of the tracker on rendered sequences and real recordings.

mod accuracy;
mod brownian;
mod common;
mod crossing;
mod errors;
mod events;
mod fixtures;
mod marks;
mod parabola;
mod real;
mod scenes;
mod styles;
mod sweep;
mod thrown;
mod traps;
