//! Physical units: fitted values in px-based units converted to SI with the image scale,
//! and values printed rounded to their standard error.
//!
//! physfit fits in px, s and the structure's mass unit. With a scale `s` (m/px) a value in
//! `px^a/s^b` is `s^a` times that in `m^a/s^b`; the structure's masses are then taken as kg,
//! so a spring stiffness (energy/px², that is mass/s²) is in N/m and a torsion stiffness
//! (energy, mass px²/s²) in J.

use serde::Serialize;

/// What a report says about its units when a scale is known (`"units"` in the JSON reports).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Units {
    /// The image scale, m/px.
    pub metres_per_px: f64,
    /// The unit the structure's masses are taken in: `kg`.
    pub mass_unit: &'static str,
    /// The same in words, for the reports.
    pub text: String,
}

impl Units {
    /// The units of a report at scale `metres_per_px`, m/px.
    pub fn new(metres_per_px: f64) -> Units {
        Units {
            metres_per_px,
            mass_unit: "kg",
            text: format!(
                "scale {} m/px ({} px/m); SI values take the structure's masses as kg",
                significant(metres_per_px, 5),
                significant(1.0 / metres_per_px, 5)
            ),
        }
    }
}

/// A px-based unit's SI unit and the power of the scale (m/px) that converts a value to it:
/// `px/s^2` -> (`m/s^2`, 1), `1/px` -> (`1/m`, -1), `energy` -> (`J`, 2). `None` for units with
/// no length in them (`1/s`, `mass/s`, dimensionless), whose value is already SI with masses
/// in kg, and for units not known here.
pub fn si_unit(unit: &str) -> Option<(&'static str, i32)> {
    Some(match unit {
        "px" => ("m", 1),
        "px/s" => ("m/s", 1),
        "px/s^2" => ("m/s^2", 1),
        "1/px" => ("1/m", -1),
        "energy/px^2" => ("N/m", 0),
        "energy" => ("J", 2),
        "mass/s" => ("kg/s", 0),
        "1/s" => ("1/s", 0),
        _ => return None,
    })
}

/// A value and its standard error in SI: `(value, std_error, unit)`, or `None` when the unit
/// has no SI form (see [`si_unit`]).
pub fn to_si(
    value: f64,
    std_error: Option<f64>,
    unit: &str,
    metres_per_px: f64,
) -> Option<(f64, Option<f64>, &'static str)> {
    let (si, power) = si_unit(unit)?;
    let k = metres_per_px.powi(power);
    Some((value * k, std_error.map(|e| e * k), si))
}

/// `value ± std_error` rounded to the standard error: the error to 2 significant digits when
/// its first digit is 1 or 2, else to 1, and the value to the same decimal place
/// (`9.79 ± 0.04`, `1808 ± 12`, `1810 ± 130`); very large or small magnitudes in scientific
/// form (`(3.07 ± 0.12)e-7`). Without a finite positive error, the value to 6 significant
/// digits. Never prints NaN: a non-finite value is `not measured`.
pub fn format_value_se(value: f64, std_error: Option<f64>) -> String {
    if !value.is_finite() {
        return "not measured".into();
    }
    let Some(se) = std_error.filter(|e| e.is_finite() && *e > 0.0) else {
        return significant(value, 6);
    };
    let lead = se.log10().floor() as i32;
    let first_digit = (se / 10f64.powi(lead)).floor();
    let digits = if first_digit < 3.0 { 2 } else { 1 };
    // The decimal place of the error's last kept digit: 10^place.
    // Rounding may carry the error to one more digit (0.096 -> 0.10): the place stays.
    let place = lead - (digits - 1);
    let top = value.abs().max(se);
    let exponent = top.log10().floor() as i32;
    if (-4..6).contains(&exponent) && place > -10 {
        let decimals = (-place).max(0) as usize;
        let round = |v: f64| (v / 10f64.powi(place)).round() * 10f64.powi(place);
        format!("{:.*} ± {:.*}", decimals, round(value), decimals, round(se))
    } else {
        let scale = 10f64.powi(exponent);
        let decimals = (exponent - place).max(0) as usize;
        format!(
            "({:.*} ± {:.*})e{exponent}",
            decimals,
            value / scale,
            decimals,
            se / scale
        )
    }
}

/// `value unit` or `value ± error unit` (see [`format_value_se`]).
pub fn format_quantity(value: f64, std_error: Option<f64>, unit: &str) -> String {
    let v = format_value_se(value, std_error);
    if unit.is_empty() || unit == "1" {
        v
    } else {
        format!("{v} {unit}")
    }
}

/// `v` to `n` significant digits, without trailing zeros after a decimal point; scientific
/// form beyond 1e-4..1e6.
pub fn significant(v: f64, n: usize) -> String {
    if !v.is_finite() {
        return "not measured".into();
    }
    if v == 0.0 {
        return "0".into();
    }
    let exponent = v.abs().log10().floor() as i32;
    if (-4..6).contains(&exponent) {
        let decimals = (n as i32 - 1 - exponent).max(0) as usize;
        let s = format!("{v:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        format!("{:.*e}", n.saturating_sub(1), v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_are_rounded_to_their_standard_error() {
        assert_eq!(format_value_se(9.7913, Some(0.0412)), "9.79 ± 0.04");
        assert_eq!(format_value_se(1808.291147, Some(12.4)), "1808 ± 12");
        assert_eq!(format_value_se(1808.291147, Some(124.0)), "1810 ± 120");
        assert_eq!(format_value_se(1808.291147, Some(460.0)), "1800 ± 500");
        assert_eq!(format_value_se(0.30112, Some(0.0021)), "0.3011 ± 0.0021");
        assert_eq!(format_value_se(-0.4860, Some(0.0963)), "-0.49 ± 0.10");
        assert_eq!(format_value_se(2.0, Some(0.5)), "2.0 ± 0.5");
        assert_eq!(format_value_se(3.07e-7, Some(1.2e-8)), "(3.07 ± 0.12)e-7");
        assert_eq!(format_value_se(59829.3955, Some(3.1)), "59829 ± 3");
        assert_eq!(format_value_se(1.5e7, Some(2.0e5)), "(1.500 ± 0.020)e7");
        assert_eq!(format_value_se(0.0, Some(0.04)), "0.00 ± 0.04");
    }

    #[test]
    fn without_an_error_six_significant_digits() {
        assert_eq!(format_value_se(1808.291147, None), "1808.29");
        assert_eq!(format_value_se(1808.291147, Some(f64::NAN)), "1808.29");
        assert_eq!(format_value_se(0.5, Some(0.0)), "0.5");
        assert_eq!(format_value_se(f64::NAN, Some(1.0)), "not measured");
        assert_eq!(
            format_quantity(9.7913, Some(0.0412), "m/s^2"),
            "9.79 ± 0.04 m/s^2"
        );
        assert_eq!(format_quantity(0.5, None, "1"), "0.5");
    }

    #[test]
    fn si_conversion_by_unit() {
        let s = 1.0 / 182.0;
        let (v, e, u) = to_si(1770.0, Some(5.0), "px/s^2", s).unwrap();
        assert!((v - 9.725).abs() < 1e-3 && (e.unwrap() - 5.0 / 182.0).abs() < 1e-12);
        assert_eq!(u, "m/s^2");
        assert!((to_si(0.01, None, "1/px", s).unwrap().0 - 1.82).abs() < 1e-12);
        assert_eq!(to_si(3.0, None, "energy/px^2", s).unwrap(), (3.0, None, "N/m"));
        assert!((to_si(182.0 * 182.0, None, "energy", s).unwrap().0 - 1.0).abs() < 1e-12);
        assert_eq!(to_si(0.5, None, "1", s), None);
    }
}
