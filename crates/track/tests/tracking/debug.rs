use crate::common::*;
use physfit_track::TrackOptions;

#[test]
#[ignore]
fn debug_noise5() {
    let truth = grid_walk(8, 8, 64.0, 12.0, 3.0, 40, 7);
    let dir = TempDir::new("dbg");
    render_to(&truth, &issue_settings(512, 512, 5.0, 101), dir.path());
    let out = track(dir.path(), &TrackOptions::default());
    let tt = truth.table(512, 512);
    for p in &out.table.points {
        let near = tt
            .points
            .iter()
            .filter(|t| t.frame == p.frame)
            .map(|t| ((t.x - p.x).hypot(t.y - p.y), t.particle.clone()))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .unwrap();
        if near.0 > 0.2 {
            println!("frame {} track {} at ({:.2},{:.2}) mass {:.0} size {:.2} flag {:?}: nearest truth {} at {:.2}", p.frame, p.particle, p.x, p.y, p.mass, p.size, p.flag, near.1, near.0);
        }
    }
    println!("{:?}", out.warnings);
}
