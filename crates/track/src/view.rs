//! What of a frame a particle's centre may be written at: not within its radius of the
//! image's edge, where part of it is cut off and the centroid of the rest leans inward (see
//! the tracker's border rule, `pipeline::border`).

use crate::TrackTable;

/// Distance, px, from `(x, y)` (pixel centres at integers) to the nearest edge of a `size`
/// (width, height px) image, which spans `-0.5` to `width - 0.5` and `-0.5` to
/// `height - 0.5`; negative outside it.
pub fn edge_distance(x: f64, y: f64, size: (usize, usize)) -> f64 {
    let (w, h) = (size.0 as f64, size.1 as f64);
    (x + 0.5).min(w - 0.5 - x).min(y + 0.5).min(h - 0.5 - y)
}

/// The points of `table` whose centre lies at least `reach` px inside a `size` image (see
/// [`edge_distance`]): the truth a tracker that writes no point of a particle cut by the
/// border, at radius `reach`, can be asked for.
pub fn in_view(table: &TrackTable, size: (usize, usize), reach: f64) -> TrackTable {
    TrackTable {
        points: table
            .points
            .iter()
            .filter(|p| edge_distance(p.x, p.y, size) >= reach)
            .cloned()
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TrackPoint;

    #[test]
    fn the_edge_is_half_a_pixel_beyond_the_outer_pixel_centres() {
        let size = (100, 50);
        assert!((edge_distance(0.0, 25.0, size) - 0.5).abs() < 1e-12);
        assert!((edge_distance(99.0, 25.0, size) - 0.5).abs() < 1e-12);
        assert!((edge_distance(50.0, 49.0, size) - 0.5).abs() < 1e-12);
        assert!((edge_distance(50.0, 20.0, size) - 20.5).abs() < 1e-12);
        assert!((edge_distance(-3.0, 20.0, size) + 2.5).abs() < 1e-12);
        let table = TrackTable {
            points: vec![
                TrackPoint::new(0, "a", 10.0, 10.0),
                TrackPoint::new(0, "b", 3.0, 10.0),
                TrackPoint::new(0, "c", 50.0, 48.0),
            ],
        };
        let kept: Vec<String> = in_view(&table, size, 4.0)
            .points
            .into_iter()
            .map(|p| p.particle)
            .collect();
        assert_eq!(kept, ["a"]);
    }
}
