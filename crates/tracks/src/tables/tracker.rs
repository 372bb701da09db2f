//! Tracker's data export (Open Source Physics; File > Export > Data, or a copied data table):
//! per mass, columns `t, x, y` (time, s; position in world units with y up), comma-, tab- or
//! semicolon-separated. An optional first line names the masses (`mass A`, over each group's
//! first column); several masses stand side by side (`t,x,y,t,x,y`) or share one time column
//! with suffixed headers (`t,x_A,y_A,x_B,y_B`); a header may carry a unit (`x (m)`).
//!
//! Conversion, as documented in `docs/tables.md`:
//! * frame = round((t - t0) / dt), with t0 the earliest time in the table and dt the frame
//!   interval read from the time columns (their smallest spacing, averaged over spacings
//!   within 10 % of it); a time more than 0.2 dt off that grid is an error;
//! * x_px = origin_x + x * s and y_px = origin_y - y * s (y flips from up to down), with
//!   s = px per world unit: `px_per_unit`, else the header's unit with `metres_per_px`, else
//!   world units taken as metres when `metres_per_px` is given, else 1 (an uncalibrated
//!   project, in px; a warning says so). The origin is Tracker's world origin in the image,
//!   px, `[0, 0]` unless given.

use std::path::Path;

use super::{finish, records, unit_metres, ForeignTable, Parsed, Row, TableFormat, TableOptions};
use crate::{TableError, TrackPoint};

/// What a Tracker column holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Kind {
    /// Time, s.
    T,
    /// World x.
    X,
    /// World y (up).
    Y,
    /// Anything else (velocities, angles...), ignored.
    Other,
}

/// A header cell's kind, the mass suffix (`x_A` -> `A`) and unit (`x (m)` -> `m`).
pub(super) fn column_kind(cell: &str) -> (Kind, Option<String>, Option<String>) {
    let (name, unit) = match cell.split_once('(') {
        Some((n, u)) => (n.trim(), Some(u.trim_end_matches(')').trim().to_string())),
        None => (cell.trim(), None),
    };
    let (base, suffix) = match name.split_once('_') {
        Some((b, s)) if !s.is_empty() => (b, Some(s.to_string())),
        _ => (name, None),
    };
    let kind = match base {
        "t" => Kind::T,
        "x" => Kind::X,
        "y" => Kind::Y,
        _ => Kind::Other,
    };
    (kind, suffix, unit)
}

/// One mass's columns.
struct Group {
    name: String,
    t: usize,
    x: usize,
    y: usize,
}

/// Reads a Tracker data export.
pub(super) fn read(text: &str, path: &Path, options: &TableOptions) -> Result<ForeignTable, TableError> {
    let rows = records(text, path)?;
    let kinds_of = |cells: &[String]| -> Vec<_> { cells.iter().map(|c| column_kind(c)).collect() };
    let is_header = |k: &[(Kind, Option<String>, Option<String>)]| {
        [Kind::T, Kind::X, Kind::Y]
            .iter()
            .all(|want| k.iter().any(|c| c.0 == *want))
    };
    let Some(h) = (0..rows.len().min(2)).find(|&i| is_header(&kinds_of(&rows[i].1))) else {
        return Err(TableError::Csv {
            path: path.to_path_buf(),
            line: rows.first().map_or(1, |r| r.0),
            message: "no `t, x, y` header in the first two lines (a Tracker data export has one)".into(),
        });
    };
    let (header_line, header) = (&rows[h].0, &rows[h].1);
    let names: Option<&Vec<String>> = (h == 1).then(|| &rows[0].1);
    let kinds = kinds_of(header);
    let find = |kind: Kind, suffix: &Option<String>, from: usize| -> Option<usize> {
        let same = kinds
            .iter()
            .position(|k| k.0 == kind && suffix.is_some() && k.1 == *suffix);
        same.or_else(|| match kind {
            // A time column: the nearest at or before the x column, else the first.
            Kind::T => (0..=from)
                .rev()
                .find(|&c| kinds[c].0 == Kind::T)
                .or_else(|| kinds.iter().position(|k| k.0 == Kind::T)),
            // A y column: the first after the x column.
            _ => (from..kinds.len()).find(|&c| kinds[c].0 == kind),
        })
    };
    let mut groups = Vec::new();
    for (c, k) in kinds.iter().enumerate().filter(|(_, k)| k.0 == Kind::X) {
        let (Some(t), Some(y)) = (find(Kind::T, &k.1, c), find(Kind::Y, &k.1, c)) else {
            return Err(TableError::Csv {
                path: path.to_path_buf(),
                line: *header_line,
                message: format!("column `{}` has no matching `t` and `y` columns", header[c]),
            });
        };
        let start = t.min(c);
        let from_names = names.and_then(|n| {
            (0..=start.min(n.len().saturating_sub(1)))
                .rev()
                .map(|i| n[i].trim())
                .find(|s| !s.is_empty())
        });
        let name = match (&k.1, from_names) {
            (Some(s), _) => s.clone(),
            (None, Some(n)) if !groups.iter().any(|g: &Group| g.name == n) => n.to_string(),
            _ => format!("{}", groups.len() + 1),
        };
        groups.push(Group { name, t, x: c, y });
    }

    // Scale, px per world unit.
    let mut warnings = Vec::new();
    let header_unit = kinds[groups[0].x].2.clone();
    let scale = match (options.px_per_unit, &header_unit, options.metres_per_px) {
        (Some(ppu), _, _) => ppu,
        (None, Some(u), mpp) => match (unit_metres(u), mpp) {
            (Ok(None), _) => 1.0,
            (Ok(Some(m)), Some(mpp)) => m / mpp,
            (Ok(Some(_)), None) => {
                return Err(TableError::Csv {
                    path: path.to_path_buf(),
                    line: *header_line,
                    message: format!(
                        "positions are in {u}: give the scale (--scale M_PER_PX, `[recording] metres_per_px` in the structure, or --px-per-unit)"
                    ),
                })
            }
            (Err(()), _) => {
                return Err(TableError::Csv {
                    path: path.to_path_buf(),
                    line: *header_line,
                    message: format!("positions are in {u}, a unit physfit does not know: give --px-per-unit"),
                })
            }
        },
        (None, None, Some(mpp)) => {
            warnings.push(format!(
                "Tracker positions taken as metres (the export names no unit), {:.6} px per m",
                1.0 / mpp
            ));
            1.0 / mpp
        }
        (None, None, None) => {
            warnings.push(
                "Tracker positions taken as px (no scale given and the export names no unit)".into(),
            );
            1.0
        }
    };

    // Every point with its time, then the frame grid.
    let mut raw: Vec<(u64, usize, f64, f64, f64, usize)> = Vec::new();
    for (line, cells) in &rows[h + 1..] {
        let row = Row {
            path,
            line: *line,
            cells,
            header,
        };
        // A row shorter than the header was cut (Tracker writes every cell, empty or not).
        row.cell(header.len() - 1)?;
        for (g, group) in groups.iter().enumerate() {
            // Tracker leaves a mass's cells empty in frames where it is not marked.
            if [group.t, group.x, group.y].iter().any(|&c| cells[c].is_empty()) {
                continue;
            }
            raw.push((
                *line,
                g,
                row.number(group.t)?,
                row.number(group.x)?,
                row.number(group.y)?,
                group.t,
            ));
        }
    }
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); groups.len()];
    for r in &raw {
        times[r.1].push(r.2);
    }
    let mut spacings: Vec<f64> = Vec::new();
    for t in &mut times {
        t.sort_by(f64::total_cmp);
        spacings.extend(t.windows(2).map(|w| w[1] - w[0]).filter(|d| *d > 0.0));
    }
    let Some(min) = spacings.iter().copied().reduce(f64::min) else {
        return Err(TableError::Csv {
            path: path.to_path_buf(),
            line: *header_line,
            message: "fewer than two distinct times: the frame interval cannot be read".into(),
        });
    };
    let near: Vec<f64> = spacings.into_iter().filter(|d| *d <= 1.1 * min).collect();
    let dt = near.iter().sum::<f64>() / near.len() as f64;
    let t0 = raw.iter().map(|r| r.2).fold(f64::INFINITY, f64::min);
    let mut points = Vec::with_capacity(raw.len());
    for &(line, g, t, x, y, tcol) in &raw {
        let k = (t - t0) / dt;
        if k.round() > f64::from(u32::MAX) {
            return Err(TableError::Cell {
                path: path.to_path_buf(),
                line,
                column: header[tcol].clone(),
                message: format!(
                    "time {t} s is frame {:.0} of the grid (interval {dt} s from {t0} s): not a frame index",
                    k.round()
                ),
            });
        }
        if (k - k.round()).abs() > 0.2 {
            return Err(TableError::Cell {
                path: path.to_path_buf(),
                line,
                column: header[tcol].clone(),
                message: format!("time {t} s is off the frame grid (interval {dt} s from {t0} s)"),
            });
        }
        let point = TrackPoint::new(
            k.round() as usize,
            groups[g].name.clone(),
            options.origin_px[0] + scale * x,
            options.origin_px[1] - scale * y,
        );
        points.push(Parsed { line, point });
    }
    Ok(ForeignTable {
        table: finish(points, path)?,
        format: TableFormat::Tracker,
        warnings,
        fps: Some(1.0 / dt),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opts() -> TableOptions {
        TableOptions {
            px_per_unit: Some(100.0),
            origin_px: [10.0, 200.0],
            ..TableOptions::default()
        }
    }

    #[test]
    fn one_mass_with_a_name_line_tab_separated() {
        let text = "mass A\nt\tx\ty\n0.1\t0.5\t1.0\n0.2\t0.6\t0.9\n0.4\t0.8\t0.5\n";
        let t = read(text, Path::new("tr.txt"), &opts()).unwrap();
        let p = &t.table.points;
        assert_eq!(p.len(), 3);
        assert_eq!(p[0].particle, "mass A");
        assert_eq!(p.iter().map(|p| p.frame).collect::<Vec<_>>(), [0, 1, 3]);
        assert!(
            (p[0].x - 60.0).abs() < 1e-9 && (p[0].y - 100.0).abs() < 1e-9,
            "{:?}",
            p[0]
        );
        assert!((t.fps.unwrap() - 10.0).abs() < 1e-9);
    }

    #[test]
    fn several_masses_side_by_side_and_suffixed() {
        let text = "mass A,,,mass B,,\nt,x,y,t,x,y\n0,0,0,0,1,1\n0.5,0.1,0,,,\n1,0.2,0,1,1.2,1\n";
        let t = read(text, Path::new("tr.csv"), &opts()).unwrap();
        assert_eq!(t.table.particle_ids(), ["mass A", "mass B"]);
        assert_eq!(t.table.points.len(), 5);
        let text = "t,x_A,y_A,x_B,y_B\n0,0,0,1,1\n0.5,0.1,0,1.1,1\n";
        let t = read(text, Path::new("tr.csv"), &opts()).unwrap();
        assert_eq!(t.table.particle_ids(), ["A", "B"]);
    }

    #[test]
    fn units_in_headers_and_scales() {
        let text = "t (s),x (cm),y (cm)\n0,1,1\n0.5,2,1\n";
        let e = read(text, Path::new("tr.csv"), &TableOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("--scale"), "{e}");
        let t = read(
            text,
            Path::new("tr.csv"),
            &TableOptions {
                metres_per_px: Some(0.001),
                ..TableOptions::default()
            },
        )
        .unwrap();
        assert!((t.table.points[1].x - 20.0).abs() < 1e-9);
        let t = read(
            "t,x,y\n0,1,1\n0.5,2,1\n",
            Path::new("tr.csv"),
            &TableOptions::default(),
        )
        .unwrap();
        assert!(t.warnings[0].contains("px"), "{:?}", t.warnings);
        assert!((t.table.points[1].y - -1.0).abs() < 1e-12);
    }

    #[test]
    fn bad_input_is_named() {
        let e = read("t,x,y\n0,1,1\n0.5,abc,1\n", Path::new("tr.csv"), &opts())
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("tr.csv:3: column `x`"), "{e}");
        let e = read(
            "t,x,y\n0,1,1\n0.5,1,1\n1.0,1,1\n1.75,1,1\n",
            Path::new("tr.csv"),
            &opts(),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("tr.csv:5: column `t`") && e.contains("frame grid"),
            "{e}"
        );
        let e = read("t,x,y\n0,1,1\n0.5,1,1\n1e30,1,1\n", Path::new("tr.csv"), &opts())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("tr.csv:4: column `t`") && e.contains("not a frame index"),
            "{e}"
        );
        let e = read("t,x,y\n0,1,1\n", Path::new("tr.csv"), &opts())
            .unwrap_err()
            .to_string();
        assert!(e.contains("two distinct times"), "{e}");
        let e = read("t,x,y\n0,1,1\n0.5,1,1\n0.5,2,2\n", Path::new("tr.csv"), &opts())
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("tr.csv:4:") && e.contains("second point"), "{e}");
        let e = read("t,x,y\n0,1,1\n0.5,1", Path::new("tr.csv"), &opts())
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("tr.csv:3:") && e.contains("truncated"), "{e}");
        let e = read("t,x,y\n0,1,1\n0.5,1,inf\n", Path::new("tr.csv"), &opts())
            .unwrap_err()
            .to_string();
        assert!(e.contains("column `y`") && e.contains("finite"), "{e}");
    }
}
