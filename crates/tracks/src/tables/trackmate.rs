//! TrackMate's spot table ("Spots" in the tracks table, exported as CSV): one row per spot,
//! `LABEL,ID,TRACK_ID,QUALITY,POSITION_X,POSITION_Y,POSITION_Z,POSITION_T,FRAME,...`.
//! TrackMate 7 writes three more header rows after the first (long names, short names and
//! units such as `(micron)` or `(pixel)`); they are skipped, and the units row gives the
//! positions' unit. Positions are in the image's calibrated units with y down and pixel
//! centres at integer multiples of the pixel size, so px = position x px-per-unit. Spots
//! with an empty `TRACK_ID` belong to no track and are skipped (counted in a warning).

use std::path::Path;

use super::{
    column, finish, header_of, records, unit_metres, ForeignTable, Parsed, Row, TableFormat, TableOptions,
};
use crate::{TableError, TrackPoint};

const NEEDS: &str = "TRACK_ID, POSITION_X, POSITION_Y, FRAME";

/// Reads a TrackMate spot table.
pub(super) fn read(text: &str, path: &Path, options: &TableOptions) -> Result<ForeignTable, TableError> {
    let rows = records(text, path)?;
    let (header_line, header) = header_of(&rows, path)?;
    let col = |name| column(header, name, NEEDS, path, header_line);
    let (track, x, y, frame) = (
        col("TRACK_ID")?,
        col("POSITION_X")?,
        col("POSITION_Y")?,
        col("FRAME")?,
    );
    // TrackMate 7's extra header rows: their POSITION_X cell is a name or a unit, not a number.
    let mut start = 1;
    let mut unit: Option<(u64, String)> = None;
    while start < rows.len().min(4) {
        let cell = rows[start].1.get(x).map(String::as_str).unwrap_or("");
        if cell.parse::<f64>().is_ok() {
            break;
        }
        if cell.starts_with('(') {
            unit = Some((rows[start].0, cell.to_string()));
        }
        start += 1;
    }
    let mut warnings = Vec::new();
    let scale = match (&unit, options.px_per_unit) {
        (_, Some(ppu)) => ppu,
        (None, None) => {
            warnings.push("the TrackMate table has no units row: positions are taken as px".into());
            1.0
        }
        (Some((line, u)), None) => match unit_metres(u) {
            Ok(None) => 1.0,
            Ok(Some(m)) => match options.metres_per_px {
                Some(mpp) => m / mpp,
                None => {
                    return Err(TableError::Csv {
                        path: path.to_path_buf(),
                        line: *line,
                        message: format!(
                            "positions are in {u}, not pixels: give the scale (--scale M_PER_PX, `[recording] metres_per_px` in the structure, or --px-per-unit)"
                        ),
                    })
                }
            },
            Err(()) => {
                return Err(TableError::Csv {
                    path: path.to_path_buf(),
                    line: *line,
                    message: format!("positions are in {u}, a unit physfit does not know: give --px-per-unit"),
                })
            }
        },
    };
    let mut untracked = 0usize;
    let mut points = Vec::with_capacity(rows.len());
    for (line, cells) in &rows[start..] {
        let row = Row {
            path,
            line: *line,
            cells,
            header,
        };
        let Some(name) = row.name(track)? else {
            untracked += 1;
            continue;
        };
        let point = TrackPoint::new(
            row.index(frame)?,
            name,
            scale * row.number(x)?,
            scale * row.number(y)?,
        );
        points.push(Parsed { line: *line, point });
    }
    if untracked > 0 {
        warnings.push(format!(
            "{untracked} spot(s) with an empty TRACK_ID (in no track) skipped"
        ));
    }
    Ok(ForeignTable {
        table: finish(points, path)?,
        format: TableFormat::TrackMate,
        warnings,
        fps: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADER: &str =
        "LABEL,ID,TRACK_ID,QUALITY,POSITION_X,POSITION_Y,POSITION_Z,POSITION_T,FRAME,RADIUS\n\
        Label,Spot ID,Track ID,Quality,X,Y,Z,T,Frame,Radius\n\
        Label,Spot ID,Track ID,Quality,X,Y,Z,T,Frame,R\n";

    fn read_str(units: &str, body: &str, options: &TableOptions) -> Result<ForeignTable, TableError> {
        let text = format!("{HEADER},,,(quality),({units}),({units}),({units}),(sec),,({units})\n{body}");
        read(&text, Path::new("tm.csv"), options)
    }

    #[test]
    fn skips_header_rows_and_untracked_spots() {
        let body = "ID1,1,0,1.0,11.0,21.0,0.0,0.1,1,2.5\nID0,0,0,1.0,10.0,20.0,0.0,0.0,0,2.5\nID9,9,,1.0,50.0,50.0,0.0,0.0,0,2.5\n";
        let t = read_str("pixel", body, &TableOptions::default()).unwrap();
        assert_eq!(t.table.points.len(), 2);
        assert_eq!(t.table.points[0].frame, 0);
        assert!((t.table.points[0].x - 10.0).abs() < 1e-12);
        assert!(t.warnings[0].contains("1 spot(s)"), "{:?}", t.warnings);
    }

    #[test]
    fn calibrated_units_need_a_scale() {
        let body = "ID0,0,0,1.0,1.5,2.0,0.0,0.0,0,2.5\n";
        let e = read_str("micron", body, &TableOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("tm.csv:4:") && e.contains("micron") && e.contains("--scale"),
            "{e}"
        );
        let with = |o: TableOptions| read_str("micron", body, &o).unwrap().table.points[0].clone();
        let p = with(TableOptions {
            px_per_unit: Some(4.0),
            ..TableOptions::default()
        });
        assert_eq!((p.x, p.y), (6.0, 8.0));
        let p = with(TableOptions {
            metres_per_px: Some(0.5e-6),
            ..TableOptions::default()
        });
        assert!((p.x - 3.0).abs() < 1e-12 && (p.y - 4.0).abs() < 1e-12, "{p:?}");
        let e = read_str("furlong", body, &TableOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("--px-per-unit"), "{e}");
    }

    #[test]
    fn bad_cells_are_named() {
        let e = read_str(
            "pixel",
            "ID0,0,0,1.0,NaN,2.0,0.0,0.0,0,2.5\n",
            &TableOptions::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("tm.csv:5: column `POSITION_X`"), "{e}");
        let e = read_str(
            "pixel",
            "ID0,0,0,1.0,1.0,2.0,0.0,0.0,x,2.5\n",
            &TableOptions::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("column `FRAME`"), "{e}");
    }
}
