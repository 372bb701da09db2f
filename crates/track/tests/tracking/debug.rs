use physfit_model::{Colour, RenderSettings};
use physfit_track::*;
use crate::common::*;

#[test]
#[ignore]
fn debug_style() {
    let truth = grid_walk(4, 4, 64.0, 12.0, 3.0, 25, 1);
    let settings = RenderSettings { width: 256, height: 256, radius: 4.5, background: Colour::Grey(20), foreground: Colour::Grey(220), noise: 5.0, blur: 0.0, seed: 11 };
    let dir = TempDir::new("dbgs");
    render_to(&truth, &settings, dir.path());
    let out = track(dir.path(), &TrackOptions { named_start: Some(truth.named_start()), ..TrackOptions::default() });
    println!("{}", out.stats);
    for p in &out.table.points {
        let i: usize = p.particle[1..].parse().unwrap();
        let t = truth.frames[p.frame][i];
        let e = (p.x - t.x).hypot(p.y - t.y);
        if e > 0.5 { println!("f{} {} err {:.2} flag {:?} mass {:.0} size {:.2}", p.frame, p.particle, e, p.flag, p.mass, p.size); }
    }
}
