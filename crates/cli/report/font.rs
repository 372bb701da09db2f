//! The font of every chart: DejaVu Sans, embedded in the binary and registered with plotters once.

use std::sync::OnceLock;

use plotters::style::{FontStyle, IntoFont, TextStyle};

/// DejaVu Sans 2.37 (Bitstream Vera licence, `assets/fonts/LICENSE-DejaVu.txt`). Embedded so that a chart looks
/// the same on every machine and needs no font installed at run time.
const DEJAVU_SANS: &[u8] = include_bytes!("../../../assets/fonts/DejaVuSans.ttf");

/// The family name the embedded font is registered under (a private name, so no other family is ever picked).
pub(crate) const FAMILY: &str = "physfit-dejavu-sans";

static REGISTERED: OnceLock<Result<(), String>> = OnceLock::new();

/// Registers the embedded font with plotters (once per process); every picture function calls this first.
pub(crate) fn ensure_registered() -> anyhow::Result<()> {
    REGISTERED
        .get_or_init(|| {
            plotters::style::register_font(FAMILY, FontStyle::Normal, DEJAVU_SANS)
                .map_err(|_| "the embedded DejaVu Sans font could not be parsed".to_owned())
        })
        .clone()
        .map_err(anyhow::Error::msg)
}

/// A text style in the embedded font, `size` pixels high, black.
pub(crate) fn text(size: f64) -> TextStyle<'static> {
    (FAMILY, size).into_font().color(&plotters::style::BLACK)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_font_registers_and_measures_text() {
        ensure_registered().unwrap();
        // A font that failed to register would make plotters report FontUnavailable here.
        let style = text(20.0);
        let (w, _) = style.font.box_size("physfit").expect("text layout");
        assert!(w > 40 && w < 120, "width of 'physfit' at 20 px: {w}");
    }
}
