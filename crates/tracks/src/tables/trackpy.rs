//! trackpy's linked DataFrame as `DataFrame.to_csv` writes it: an unnamed index column
//! first, then `y,x,mass,size,ecc,signal,raw_mass,ep,frame,particle` (any order, other
//! columns ignored). Frames and particles may be written as floats (`3.0`) after pandas
//! operations that introduce NaN elsewhere. Positions are px, pixel centres at integers,
//! y down: physfit's own conventions (physfit's column names are trackpy's).

use std::path::Path;

use super::{column, finish, header_of, records, ForeignTable, Parsed, Row, TableFormat};
use crate::{TableError, TrackPoint};

const NEEDS: &str = "frame, particle, x, y";

/// Reads a trackpy CSV.
pub(super) fn read(text: &str, path: &Path) -> Result<ForeignTable, TableError> {
    let rows = records(text, path)?;
    let (header_line, header) = header_of(&rows, path)?;
    let col = |name| column(header, name, NEEDS, path, header_line);
    let (f, p, x, y) = (col("frame")?, col("particle")?, col("x")?, col("y")?);
    let optional = |name: &str| header.iter().position(|h| h == name);
    let (mass, size, ep) = (optional("mass"), optional("size"), optional("ep"));
    let mut points = Vec::with_capacity(rows.len());
    for (line, cells) in &rows[1..] {
        let row = Row {
            path,
            line: *line,
            cells,
            header,
        };
        let particle = row
            .name(p)?
            .ok_or_else(|| row.error(p, "empty particle (an unlinked feature?)".into()))?;
        let mut point = TrackPoint::new(row.index(f)?, particle, row.number(x)?, row.number(y)?);
        // Optional columns: an empty cell, or NaN (trackpy's ep of a bad fit), stays unknown.
        let extra = |c: Option<usize>| -> Result<f64, TableError> {
            match c.map(|c| row.cell(c)).transpose()? {
                None | Some("") => Ok(f64::NAN),
                Some(s) => s
                    .parse::<f64>()
                    .map_err(|_| row.error(c.unwrap_or(0), format!("`{s}` is not a number"))),
            }
        };
        point.mass = extra(mass)?;
        point.size = extra(size)?;
        point.ep = extra(ep)?;
        points.push(Parsed { line: *line, point });
    }
    Ok(ForeignTable {
        table: finish(points, path)?,
        format: TableFormat::Trackpy,
        warnings: Vec::new(),
        fps: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADER: &str = ",y,x,mass,size,ecc,signal,raw_mass,ep,frame,particle\n";

    fn read_str(body: &str) -> Result<ForeignTable, TableError> {
        read(&format!("{HEADER}{body}"), Path::new("tp.csv"))
    }

    #[test]
    fn reads_columns_in_trackpys_order_with_float_ids() {
        let t = read_str("0,20.5,10.25,300.0,2.1,0.05,40.0,900.0,0.02,0.0,3.0\n1,21.0,11.0,300.0,2.1,0.05,40.0,900.0,,1.0,3.0\n")
            .unwrap()
            .table;
        assert_eq!(t.points.len(), 2);
        assert_eq!(t.points[0].particle, "3");
        assert_eq!(t.points[1].frame, 1);
        assert!((t.points[0].x - 10.25).abs() < 1e-12);
        assert!((t.points[0].y - 20.5).abs() < 1e-12);
        assert!((t.points[0].ep - 0.02).abs() < 1e-12);
        assert!(t.points[1].ep.is_nan());
    }

    #[test]
    fn bad_cells_name_file_line_and_column() {
        let e = read_str("0,20.5,abc,1,1,1,1,1,0.1,0,3\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("tp.csv:2: column `x`"), "{e}");
        let e = read_str("0,20.5,inf,1,1,1,1,1,0.1,0,3\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("column `x`") && e.contains("finite"), "{e}");
        let e = read_str("0,nan,1,1,1,1,1,1,0.1,0,3\n").unwrap_err().to_string();
        assert!(e.contains("column `y`"), "{e}");
        let e = read_str("0,1,1,1,1,1,1,1,0.1,0.5,3\n").unwrap_err().to_string();
        assert!(e.contains("column `frame`") && e.contains("frame index"), "{e}");
    }

    #[test]
    fn truncated_rows_duplicates_and_missing_columns_are_errors() {
        let e = read_str("0,1,1,1,1,1,1,1,0.1,0,3\n1,1,1,1")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("tp.csv:3:") && e.contains("truncated"), "{e}");
        let e = read_str("0,1,1,1,1,1,1,1,0.1,0,3\n1,2,2,1,1,1,1,1,0.1,0,3\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("tp.csv:3:") && e.contains("second point in frame 0"),
            "{e}"
        );
        let e = read(",y,x,frame\n0,1,1,0\n", Path::new("tp.csv"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing column `particle`"), "{e}");
    }
}
