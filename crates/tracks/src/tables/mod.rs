//! Other trackers' tables: trackpy CSVs, TrackMate spot-table exports and Tracker (Open
//! Source Physics) data exports, read into physfit's [`TrackTable`] (frames as 0-based
//! indices, positions in px with x right and y down, pixel centres at integers).
//!
//! A key design decision: every reader ends in the same [`TrackTable`] and checks the same
//! things (finite numbers, integer frames, one point per track and frame), with errors naming
//! the file, the 1-based line and the column, so `fit` and `diagnose` see one kind of input
//! whatever made it. The format is detected from the header ([`detect_format`]) or named.
//! Track names that are not the structure's particle ids are matched to the structure by
//! first-frame position afterwards, by the tracker's `name_tracks_by_position` (it needs
//! the tracker's optimal assignment, so it lives in `physfit-track`).
//!
//! What each format's columns mean and what is assumed is in `docs/tables.md`.

mod tracker;
mod trackmate;
mod trackpy;

use std::collections::HashSet;
use std::path::Path;

use crate::{TableError, TrackTable};

/// A track table's format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TableFormat {
    /// physfit's own `frame,particle,x,y[,mass,size,ep,flag]` CSV.
    Physfit,
    /// trackpy's linked DataFrame written by `to_csv` (an unnamed index column first, then
    /// `y,x,mass,size,ecc,signal,raw_mass,ep,frame,particle` in any order).
    Trackpy,
    /// TrackMate's spot table (`LABEL,ID,TRACK_ID,QUALITY,POSITION_X,...,FRAME,...`), with or
    /// without its three extra header rows (long names, short names, units).
    TrackMate,
    /// Tracker's data export: `t,x,y` per mass, world coordinates (y up, calibrated units).
    Tracker,
}

impl TableFormat {
    /// The format's name as `--format` spells it.
    pub fn name(self) -> &'static str {
        match self {
            TableFormat::Physfit => "physfit",
            TableFormat::Trackpy => "trackpy",
            TableFormat::TrackMate => "trackmate",
            TableFormat::Tracker => "tracker",
        }
    }
}

impl std::fmt::Display for TableFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// How to read a track table.
#[derive(Clone, Debug, PartialEq)]
pub struct TableOptions {
    /// The format; `None` = detected from the header.
    pub format: Option<TableFormat>,
    /// Pixels per unit of the table's positions (TrackMate's calibrated units, Tracker's world
    /// units), px/unit. Takes precedence over `metres_per_px`.
    pub px_per_unit: Option<f64>,
    /// The recording's scale, m/px: converts TrackMate positions in a known length unit
    /// (micron, mm, m...) and Tracker positions (taken as metres) to px.
    pub metres_per_px: Option<f64>,
    /// Where Tracker's world origin is in the image, px (x right, y down); default `[0, 0]`.
    pub origin_px: [f64; 2],
}

impl Default for TableOptions {
    fn default() -> Self {
        TableOptions {
            format: None,
            px_per_unit: None,
            metres_per_px: None,
            origin_px: [0.0, 0.0],
        }
    }
}

/// A table read from another tool, converted to physfit's conventions.
#[derive(Clone, Debug, PartialEq)]
pub struct ForeignTable {
    /// The points, px, sorted by frame then by track order.
    pub table: TrackTable,
    /// The format read.
    pub format: TableFormat,
    /// What was skipped or assumed (spots outside tracks, units taken as px...), a sentence each.
    pub warnings: Vec<String>,
    /// The frame rate implied by the table's times, frames/s (Tracker only).
    pub fps: Option<f64>,
}

/// Reads a track table in any supported format (see [`TableOptions`]). Errors name the file,
/// the 1-based line and, for a bad cell, the column.
pub fn read_track_table(path: &Path, options: &TableOptions) -> Result<ForeignTable, TableError> {
    let bytes = std::fs::read(path).map_err(|source| TableError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let text = String::from_utf8(bytes).map_err(|e| TableError::Csv {
        path: path.to_path_buf(),
        line: 1 + e.as_bytes()[..e.utf8_error().valid_up_to()]
            .iter()
            .filter(|&&b| b == b'\n')
            .count() as u64,
        message: "not UTF-8 text".into(),
    })?;
    read_track_table_str(&text, path, options)
}

/// Reads a track table from text; `path` names it in errors.
pub fn read_track_table_str(
    text: &str,
    path: &Path,
    options: &TableOptions,
) -> Result<ForeignTable, TableError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    for (key, v) in [
        ("px per unit", options.px_per_unit),
        ("metres per px", options.metres_per_px),
    ] {
        if let Some(v) = v {
            if !(v.is_finite() && v > 0.0) {
                return Err(TableError::Option(format!("{key} {v} must be a positive number")));
            }
        }
    }
    let format = match options.format {
        Some(f) => f,
        None => detect_format(text).ok_or_else(|| TableError::Csv {
            path: path.to_path_buf(),
            line: 1,
            message: format!(
                "cannot tell the table's format from its header `{}`; name it with --format physfit|trackpy|trackmate|tracker",
                text.lines().next().unwrap_or("").chars().take(80).collect::<String>()
            ),
        })?,
    };
    let mut out = match format {
        TableFormat::Physfit => ForeignTable {
            table: TrackTable::read_from(text.as_bytes(), path)?,
            format,
            warnings: Vec::new(),
            fps: None,
        },
        TableFormat::Trackpy => trackpy::read(text, path)?,
        TableFormat::TrackMate => trackmate::read(text, path, options)?,
        TableFormat::Tracker => tracker::read(text, path, options)?,
    };
    if out.table.points.is_empty() {
        return Err(TableError::Csv {
            path: path.to_path_buf(),
            line: text.lines().count().max(1) as u64,
            message: format!("no track points in this {format} table"),
        });
    }
    out.format = format;
    Ok(out)
}

/// The format named by a table's first lines, or `None` when none fits: TrackMate by
/// `TRACK_ID` and `POSITION_X`; trackpy by `frame,particle,x,y` with an unnamed first column or
/// one of trackpy's own columns (`ecc`, `signal`, `raw_mass`); physfit by `frame,particle,x,y`
/// otherwise; Tracker by `t`, `x` and `y` columns in the first or second line.
pub fn detect_format(text: &str) -> Option<TableFormat> {
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let first = lines.next()?;
    let cells = split_header(first);
    let has = |name: &str| cells.iter().any(|c| c == name);
    if has("TRACK_ID") && has("POSITION_X") {
        return Some(TableFormat::TrackMate);
    }
    if ["frame", "particle", "x", "y"].iter().all(|n| has(n)) {
        let trackpy_only = ["ecc", "signal", "raw_mass"].iter().any(|n| has(n));
        let unnamed_index = cells.first().is_some_and(|c| c.is_empty());
        return Some(if (trackpy_only || unnamed_index) && !has("flag") {
            TableFormat::Trackpy
        } else {
            TableFormat::Physfit
        });
    }
    let second = lines.next();
    for line in std::iter::once(first).chain(second) {
        let kinds: Vec<_> = split_header(line)
            .iter()
            .map(|c| tracker::column_kind(c).0)
            .collect();
        if [tracker::Kind::T, tracker::Kind::X, tracker::Kind::Y]
            .iter()
            .all(|k| kinds.contains(k))
        {
            return Some(TableFormat::Tracker);
        }
    }
    None
}

/// A header line's cells, trimmed and unquoted, split at its delimiter.
fn split_header(line: &str) -> Vec<String> {
    line.split(delimiter_of(line) as char)
        .map(|c| c.trim().trim_matches('"').trim().to_string())
        .collect()
}

/// The delimiter of a line: tab, semicolon or comma, whichever appears (tab first).
fn delimiter_of(line: &str) -> u8 {
    if line.contains('\t') {
        b'\t'
    } else if line.contains(';') && !line.contains(',') {
        b';'
    } else {
        b','
    }
}

/// Every record of `text` with its 1-based line, cells trimmed; blank lines are left out.
fn records(text: &str, path: &Path) -> Result<Vec<(u64, Vec<String>)>, TableError> {
    // A Tracker export may open with a one-cell name line: look at the second line too.
    let first: String = text
        .lines()
        .filter(|l| !l.trim().is_empty())
        .take(2)
        .collect::<Vec<_>>()
        .join("\n");
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .delimiter(delimiter_of(&first))
        .from_reader(text.as_bytes());
    let mut out = Vec::new();
    for rec in rdr.records() {
        let rec = rec.map_err(|e| TableError::Csv {
            path: path.to_path_buf(),
            line: e.position().map_or(0, |p| p.line()),
            message: e.to_string(),
        })?;
        let line = rec.position().map_or(0, |p| p.line());
        if rec.iter().all(|c| c.is_empty()) {
            continue;
        }
        out.push((line, rec.iter().map(str::to_string).collect()));
    }
    Ok(out)
}

/// One data row of a table, for cell parsing with errors naming file, line and column.
struct Row<'a> {
    path: &'a Path,
    line: u64,
    cells: &'a [String],
    header: &'a [String],
}

impl Row<'_> {
    /// An error at this row naming `col`'s header.
    fn error(&self, col: usize, message: String) -> TableError {
        TableError::Cell {
            path: self.path.to_path_buf(),
            line: self.line,
            column: self
                .header
                .get(col)
                .cloned()
                .unwrap_or_else(|| format!("#{}", col + 1)),
            message,
        }
    }

    /// The cell in column `col`, or an error for a row too short (a truncated file).
    fn cell(&self, col: usize) -> Result<&str, TableError> {
        self.cells
            .get(col)
            .map(String::as_str)
            .ok_or_else(|| TableError::Csv {
                path: self.path.to_path_buf(),
                line: self.line,
                message: format!(
                    "the row has {} fields but the header has {} (a truncated file?)",
                    self.cells.len(),
                    self.header.len()
                ),
            })
    }

    /// The cell in column `col` as a finite number.
    fn number(&self, col: usize) -> Result<f64, TableError> {
        let s = self.cell(col)?;
        let v: f64 = s
            .parse()
            .map_err(|_| self.error(col, format!("`{s}` is not a number")))?;
        if !v.is_finite() {
            return Err(self.error(col, format!("`{s}` is not a finite number")));
        }
        Ok(v)
    }

    /// The cell in column `col` as a frame index: a non-negative integer, possibly written as
    /// a float (`3.0`).
    fn index(&self, col: usize) -> Result<usize, TableError> {
        let v = self.number(col)?;
        if v < 0.0 || v.fract() != 0.0 || v > u32::MAX as f64 {
            return Err(self.error(col, format!("{v} is not a frame index (a whole number >= 0)")));
        }
        Ok(v as usize)
    }

    /// The cell in column `col` as a track name: integers written as floats (`3.0`) lose
    /// their `.0`; an empty cell is `None`.
    fn name(&self, col: usize) -> Result<Option<String>, TableError> {
        let s = self.cell(col)?;
        if s.is_empty() {
            return Ok(None);
        }
        Ok(Some(match s.parse::<f64>() {
            Ok(v) if v.is_finite() && v.fract() == 0.0 && v.abs() < 1e15 => format!("{}", v as i64),
            _ => s.to_string(),
        }))
    }
}

/// The first record of `rows` (its line and cells): a table's header; an error naming `path`
/// when there is none.
fn header_of<'a>(rows: &'a [(u64, Vec<String>)], path: &Path) -> Result<(u64, &'a [String]), TableError> {
    rows.first()
        .map(|(line, cells)| (*line, cells.as_slice()))
        .ok_or_else(|| TableError::Csv {
            path: path.to_path_buf(),
            line: 1,
            message: "empty file: no header".into(),
        })
}

/// The column named `name` in `header`, or an error naming the missing column and the
/// columns the format needs.
fn column(header: &[String], name: &str, needs: &str, path: &Path, line: u64) -> Result<usize, TableError> {
    header
        .iter()
        .position(|h| h == name)
        .ok_or_else(|| TableError::Csv {
            path: path.to_path_buf(),
            line,
            message: format!("missing column `{name}` (need {needs})"),
        })
}

/// A length unit (`pixel`, `micron`, `mm`, `m`..., parentheses allowed) in metres: `Ok(None)`
/// for pixels (and for no unit), `Err` for a unit not known.
fn unit_metres(unit: &str) -> Result<Option<f64>, ()> {
    let u = unit.trim().trim_start_matches('(').trim_end_matches(')').trim();
    match u.to_ascii_lowercase().as_str() {
        "pixel" | "pixels" | "px" | "" => Ok(None),
        "micron" | "microns" | "um" | "µm" | "μm" | "micrometer" | "micrometre" => Ok(Some(1e-6)),
        "nm" | "nanometer" | "nanometre" => Ok(Some(1e-9)),
        "mm" | "millimeter" | "millimetre" => Ok(Some(1e-3)),
        "cm" | "centimeter" | "centimetre" => Ok(Some(1e-2)),
        "m" | "meter" | "metre" | "meters" | "metres" => Ok(Some(1.0)),
        _ => Err(()),
    }
}

/// A point of a table before sorting: its line, for duplicate errors.
struct Parsed {
    line: u64,
    point: crate::TrackPoint,
}

/// The table of `points` sorted by frame then by track order of first appearance; a second
/// point of one track in one frame is an error naming both lines.
fn finish(points: Vec<Parsed>, path: &Path) -> Result<TrackTable, TableError> {
    let mut order: Vec<&str> = Vec::new();
    let mut seen_names = HashSet::new();
    for p in &points {
        if seen_names.insert(p.point.particle.as_str()) {
            order.push(p.point.particle.as_str());
        }
    }
    let rank: std::collections::HashMap<&str, usize> =
        order.iter().enumerate().map(|(k, n)| (*n, k)).collect();
    let mut keyed: Vec<(usize, usize, u64, usize)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| (p.point.frame, rank[p.point.particle.as_str()], p.line, i))
        .collect();
    keyed.sort_unstable();
    for w in keyed.windows(2) {
        if (w[0].0, w[0].1) == (w[1].0, w[1].1) {
            let p = &points[w[1].3].point;
            return Err(TableError::Csv {
                path: path.to_path_buf(),
                line: w[1].2,
                message: format!(
                    "track {} has a second point in frame {} (the first is on line {})",
                    p.particle, p.frame, w[0].2
                ),
            });
        }
    }
    let mut slots: Vec<Option<crate::TrackPoint>> = points.into_iter().map(|p| Some(p.point)).collect();
    Ok(TrackTable {
        points: keyed.iter().filter_map(|k| slots[k.3].take()).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detects_each_format_from_its_header() {
        let d = |t: &str| detect_format(t);
        assert_eq!(
            d("frame,particle,x,y,mass,size,ep,flag\n"),
            Some(TableFormat::Physfit)
        );
        assert_eq!(d("frame,particle,x,y\n"), Some(TableFormat::Physfit));
        assert_eq!(
            d(",y,x,mass,size,ecc,signal,raw_mass,ep,frame,particle\n"),
            Some(TableFormat::Trackpy)
        );
        assert_eq!(
            d("LABEL,ID,TRACK_ID,QUALITY,POSITION_X,POSITION_Y,POSITION_Z,POSITION_T,FRAME\n"),
            Some(TableFormat::TrackMate)
        );
        assert_eq!(d("mass A\nt\tx\ty\n"), Some(TableFormat::Tracker));
        assert_eq!(d("t,x_A,y_A\n"), Some(TableFormat::Tracker));
        assert_eq!(d("a,b,c\n"), None);
    }

    /// The fixtures under `fixtures/tables/`: one pair of tracks in each tool's conventions.
    fn fixture(name: &str, options: &TableOptions) -> ForeignTable {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../fixtures/tables")
            .join(name);
        read_track_table(&path, options).unwrap_or_else(|e| panic!("{e}"))
    }

    #[test]
    fn every_fixture_reads_to_the_same_tracks() {
        let own = fixture("physfit.csv", &TableOptions::default());
        assert_eq!(own.format, TableFormat::Physfit);
        let scaled = TableOptions {
            metres_per_px: Some(0.5e-6),
            ..TableOptions::default()
        };
        let others = [
            (
                fixture("trackpy.csv", &TableOptions::default()),
                TableFormat::Trackpy,
                ["4", "11"],
            ),
            (
                fixture("trackmate.csv", &scaled),
                TableFormat::TrackMate,
                ["0", "1"],
            ),
            (
                fixture(
                    "tracker.txt",
                    &TableOptions {
                        metres_per_px: Some(0.001),
                        ..TableOptions::default()
                    },
                ),
                TableFormat::Tracker,
                ["mass A", "mass B"],
            ),
        ];
        for (t, format, names) in &others {
            assert_eq!(t.format, *format);
            assert_eq!(t.table.particle_ids(), names);
            assert_eq!(t.table.points.len(), own.table.points.len(), "{format}");
            for (p, q) in t.table.points.iter().zip(&own.table.points) {
                assert_eq!(p.frame, q.frame, "{format}");
                assert!(
                    (p.x - q.x).abs() < 1e-9 && (p.y - q.y).abs() < 1e-9,
                    "{format}: {p:?} vs {q:?}"
                );
            }
        }
        assert!(others[1].0.warnings[0].contains("1 spot(s)"));
        assert!((others[2].0.fps.unwrap() - 25.0).abs() < 1e-9);
        // The micron table without a scale: a clear error naming the units row.
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/tables/trackmate.csv");
        let e = read_track_table(&path, &TableOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("trackmate.csv:4:") && e.contains("micron"), "{e}");
    }

    #[test]
    fn an_unknown_header_asks_for_the_format() {
        let e = read_track_table_str("a,b\n1,2\n", Path::new("t.csv"), &TableOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("t.csv:1:") && e.contains("--format"), "{e}");
    }
}
