//! The report palette: one colour per particle (or series), the same in every picture.

/// The qualitative "Tableau 10" colours (also matplotlib's default cycle): distinct on white and on grey frames.
const PALETTE: [[u8; 3]; 10] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [127, 127, 127],
    [188, 189, 34],
    [23, 190, 207],
];

/// The sRGB colour of palette entry `index` (cycling after ten): the colour of particle `index` in every chart,
/// trajectory plot and overlay of a report.
pub fn palette_colour(index: usize) -> [u8; 3] {
    PALETTE[index % PALETTE.len()]
}

/// `colour` mixed towards black by `amount` in 0..=1 (0 = unchanged): a darker shade of the same hue, used to
/// tell a model's prediction from the observed track of the same particle.
pub(crate) fn darken(colour: [u8; 3], amount: f64) -> [u8; 3] {
    let keep = (1.0 - amount).clamp(0.0, 1.0);
    colour.map(|c| (f64::from(c) * keep).round() as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn palette_cycles_and_darken_keeps_hue_order() {
        assert_eq!(palette_colour(0), palette_colour(10));
        assert_ne!(palette_colour(0), palette_colour(1));
        assert_eq!(darken([200, 100, 50], 0.5), [100, 50, 25]);
        assert_eq!(darken([200, 100, 50], 0.0), [200, 100, 50]);
    }
}
