//! Unit tests of the tracking stage.

use super::finder::join_close;
use crate::Detection;

fn detection(x: f64, y: f64, mass: f64) -> Detection {
    Detection {
        x,
        y,
        mass,
        size: 1.0,
        ep: 0.01,
        follow: 0.0,
        area: 10.0,
        clipped: false,
    }
}

#[test]
fn estimates_within_a_radius_are_joined_at_their_mass_weighted_mean() {
    // Two halves of one ring (3.7 px either side of its centre at x = 20) and a particle
    // a diameter away: the halves are joined, the particle keeps its own seed.
    let found = [
        detection(16.3, 30.0, 100.0),
        detection(23.7, 30.0, 300.0),
        detection(36.0, 30.0, 200.0),
    ];
    let (seeds, areas) = join_close(&found, 8.0, |_, _| false).expect("joined");
    assert_eq!(seeds.len(), 2);
    let joined = seeds.iter().position(|s| s[0] < 30.0).expect("the joined seed");
    assert!((seeds[joined][0] - 21.85).abs() < 1e-9 && (seeds[joined][1] - 30.0).abs() < 1e-9);
    assert!((areas[joined] - 20.0).abs() < 1e-9);
    assert!(seeds.iter().any(|s| (s[0] - 36.0).abs() < 1e-9));
    // Estimates a radius or more apart are left alone, unless they are arcs of one ring
    // within two radii: 12.3 px apart here, 28.3 beside the third.
    assert!(join_close(&found[1..], 8.0, |_, _| false).is_none());
    let arcs = join_close(&found[1..], 8.0, |_, _| true).expect("arcs joined");
    assert_eq!(arcs.0.len(), 1);
    assert!(join_close(&[found[0], found[2]], 8.0, |_, _| true).is_none());
}
