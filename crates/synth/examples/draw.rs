//! Draws the style of a seed into a folder: `cargo run --release -p physfit-synth --example
//! draw -- SEED OUT_DIR` writes `frame_00000.png`, ... and `truth.csv` into OUT_DIR and prints
//! the style and its Cramér-Rao bound.

use std::path::PathBuf;

use physfit_synth::{Sequence, Style};

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let usage = "usage: draw SEED OUT_DIR";
    let seed: u64 = args.next().ok_or(usage)?.parse()?;
    let out = PathBuf::from(args.next().ok_or(usage)?);
    let seq = Sequence::new(Style::random(seed));
    seq.write_frames(&out)?;
    seq.truth.write_csv(&out.join("truth.csv"))?;
    let [bx, by] = seq.bound().sigma();
    let [ox, oy] = seq.truth.centroid_offset_rms();
    println!("{}", seq.style);
    println!("CRB sigma x {bx:.4} y {by:.4} px; intensity centroid offset RMS x {ox:.4} y {oy:.4} px");
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("draw: {e}");
        std::process::exit(1);
    }
}
