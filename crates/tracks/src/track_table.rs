//! The track table: the CSV contract between tracking and identification.
//!
//! Columns `frame,particle,x,y,mass,size` are trackpy's names and meanings; physfit adds `ep`
//! (estimated position error) and `flag` (how the point was obtained). Readers need only
//! `frame,particle,x,y` and ignore columns they do not know, so truth files
//! (`frame,particle,x,y`) are track tables too.

use std::collections::{BTreeMap, HashMap};
use std::io::Write as _;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::TableError;

/// How a track point was obtained.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PointFlag {
    /// Located in the frame from its own blob.
    #[default]
    Detected,
    /// Located by splitting a blob that held several particles.
    Split,
    /// Not seen as a blob of its own: bridged from the track's motion prediction (with a
    /// structure, placed from the image where it shares a blob with other particles).
    Interpolated,
}

/// One particle's position in one frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrackPoint {
    /// 0-based frame index (the frame file's index in natural name order).
    pub frame: usize,
    /// Track name: a structure particle id, or an integer for unnamed tracks.
    pub particle: String,
    /// Column coordinate, px (pixel centres at integers, x right).
    pub x: f64,
    /// Row coordinate, px (y down).
    pub y: f64,
    /// Integrated brightness above background, grey levels · px² (NaN when unknown).
    #[serde(default = "nan", deserialize_with = "empty_as_nan")]
    pub mass: f64,
    /// Blob radius of gyration, px (NaN when unknown).
    #[serde(default = "nan", deserialize_with = "empty_as_nan")]
    pub size: f64,
    /// Estimated standard error of `x` and `y`, px (NaN when unknown).
    #[serde(default = "nan", deserialize_with = "empty_as_nan")]
    pub ep: f64,
    /// How the point was obtained.
    #[serde(default)]
    pub flag: PointFlag,
}

fn nan() -> f64 {
    f64::NAN
}

fn empty_as_nan<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    let s: Option<String> = Option::deserialize(d)?;
    match s.as_deref().map(str::trim) {
        None | Some("") => Ok(f64::NAN),
        Some(t) => t.parse().map_err(serde::de::Error::custom),
    }
}

/// A size or an error in px rounded to 1e-6 px (the nearest `f64` to a decimal of six places, which
/// `ryu` writes in at most six), `-0` written as `0`; values beyond 1e9 px and non-finite
/// values are kept whole.
fn to_micro_px(v: f64) -> f64 {
    if v.is_finite() && v.abs() < 1e9 {
        (v * 1e6).round() / 1e6 + 0.0
    } else {
        v
    }
}

/// A mass in single precision (where it is computed), `None` where `f32` cannot hold it.
fn single(v: f64) -> Option<f32> {
    (v.is_nan() || v.abs() <= f32::MAX as f64).then_some(v as f32)
}

impl TrackPoint {
    /// A detected point with unknown mass, size and error.
    pub fn new(frame: usize, particle: impl Into<String>, x: f64, y: f64) -> Self {
        TrackPoint {
            frame,
            particle: particle.into(),
            x,
            y,
            mass: f64::NAN,
            size: f64::NAN,
            ep: f64::NAN,
            flag: PointFlag::Detected,
        }
    }
}

/// All track points of a recording, sorted by frame then by track order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TrackTable {
    /// The points.
    pub points: Vec<TrackPoint>,
}

impl TrackTable {
    /// Reads a track CSV. Needs the columns `frame,particle,x,y`; others are optional.
    /// Errors name the file and line; non-finite coordinates are errors.
    pub fn read_csv(path: &Path) -> Result<TrackTable, TableError> {
        let file = std::fs::File::open(path).map_err(|source| TableError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::read_from(file, path)
    }

    /// Reads a track CSV from any reader; `path` names it in errors.
    pub fn read_from(reader: impl std::io::Read, path: &Path) -> Result<TrackTable, TableError> {
        let mut rdr = csv::ReaderBuilder::new().trim(csv::Trim::All).from_reader(reader);
        let csv_err = |line: u64, message: String| TableError::Csv {
            path: path.to_path_buf(),
            line,
            message,
        };
        let headers = rdr.headers().map_err(|e| csv_err(1, e.to_string()))?.clone();
        for need in ["frame", "particle", "x", "y"] {
            if !headers.iter().any(|h| h == need) {
                return Err(csv_err(
                    1,
                    format!("missing column `{need}` (need frame,particle,x,y)"),
                ));
            }
        }
        let mut points = Vec::new();
        for (k, rec) in rdr.deserialize::<TrackPoint>().enumerate() {
            let line = k as u64 + 2;
            let p = rec.map_err(|e| {
                let line = e.position().map_or(line, |p| p.line());
                let msg = match e.kind() {
                    csv::ErrorKind::Deserialize { err, .. } => match err.field() {
                        Some(f) => format!(
                            "column `{}`: {}",
                            headers.get(f as usize).unwrap_or("?"),
                            err.kind()
                        ),
                        None => err.kind().to_string(),
                    },
                    _ => e.to_string(),
                };
                csv_err(line, msg)
            })?;
            if !(p.x.is_finite() && p.y.is_finite()) {
                return Err(csv_err(
                    line,
                    format!(
                        "particle {} has a non-finite position ({}, {})",
                        p.particle, p.x, p.y
                    ),
                ));
            }
            points.push(p);
        }
        Ok(TrackTable { points })
    }

    /// Writes the table as CSV (`frame,particle,x,y,mass,size,ep,flag`) atomically: a
    /// temporary file renamed into place.
    pub fn write_csv(&self, path: &Path) -> Result<(), TableError> {
        let io_err = |source| TableError::Io {
            path: path.to_path_buf(),
            source,
        };
        let bytes = self.csv_bytes().map_err(|e| io_err(std::io::Error::other(e)))?;
        crate::write_atomic(path, &bytes).map_err(io_err)
    }

    /// The table as CSV bytes: the header, then each point's fields as the `csv` crate
    /// writes them through serde once rounded (`size` and `ep` to 1e-6 px, `mass` to the single
    /// precision it is computed in; positions whole, so that a table read back fits as the
    /// one in memory: 22.0 MB to 16.1 MB for 200 000 points);
    /// integers in decimal, floats by `ryu`, the flag's lowercase
    /// name, a name quoted by `csv` itself where it holds more than letters, digits, `_`,
    /// `-` and `.`), written straight into the buffer: through serde and the `csv` writer
    /// the rows took 3.6 k instructions each (143 M of a 3.09 G tracking run at N = 1000,
    /// 40 frames, callgrind), half of them outside the float formatting.
    fn csv_bytes(&self) -> Result<Vec<u8>, csv::Error> {
        let mut out: Vec<u8> = Vec::with_capacity(64 * (self.points.len() + 1));
        out.extend_from_slice(b"frame,particle,x,y,mass,size,ep,flag\n");
        let mut float = ryu::Buffer::new();
        // Names that need more than copying, as `csv` writes them in a record's second field.
        let mut quoted: HashMap<&str, Vec<u8>> = HashMap::new();
        for p in &self.points {
            write!(out, "{},", p.frame).expect("writing to a Vec");
            let name = p.particle.as_str();
            if name
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.'))
            {
                out.extend_from_slice(name.as_bytes());
            } else {
                if !quoted.contains_key(name) {
                    let mut w = csv::Writer::from_writer(Vec::new());
                    w.write_record(["0", name])?;
                    let bytes = w.into_inner().map_err(|e| csv::Error::from(e.into_error()))?;
                    // Without the first field's "0," and the record's "\n".
                    quoted.insert(name, bytes[2..bytes.len() - 1].to_vec());
                }
                out.extend_from_slice(&quoted[name]);
            }
            for v in [p.x, p.y] {
                out.push(b',');
                out.extend_from_slice(float.format(v).as_bytes());
            }
            out.push(b',');
            match single(p.mass) {
                Some(m) => out.extend_from_slice(float.format(m).as_bytes()),
                None => out.extend_from_slice(float.format(p.mass).as_bytes()),
            }
            for v in [p.size, p.ep] {
                out.push(b',');
                out.extend_from_slice(float.format(to_micro_px(v)).as_bytes());
            }
            let flag: &[u8] = match p.flag {
                PointFlag::Detected => b",detected\n",
                PointFlag::Split => b",split\n",
                PointFlag::Interpolated => b",interpolated\n",
            };
            out.extend_from_slice(flag);
        }
        Ok(out)
    }

    /// Track names in order of first appearance.
    pub fn particle_ids(&self) -> Vec<String> {
        let mut seen = std::collections::HashSet::new();
        self.points
            .iter()
            .filter(|p| seen.insert(p.particle.as_str()))
            .map(|p| p.particle.clone())
            .collect()
    }

    /// The points of each track, by name, each sorted by frame.
    pub fn by_particle(&self) -> BTreeMap<&str, Vec<&TrackPoint>> {
        // Grouped through a hash map, the B-tree built once from the groups: an ordered-map
        // entry per point compared names about log2(tracks) times each (62 M of a 3.09 G
        // tracking run at N = 1000, 40 frames, callgrind).
        let mut group_of: HashMap<&str, usize> = HashMap::new();
        let mut groups: Vec<(&str, Vec<&TrackPoint>)> = Vec::new();
        for p in &self.points {
            let name = p.particle.as_str();
            let g = *group_of.entry(name).or_insert_with(|| {
                groups.push((name, Vec::new()));
                groups.len() - 1
            });
            groups[g].1.push(p);
        }
        for (_, v) in &mut groups {
            v.sort_by_key(|p| p.frame);
        }
        groups.into_iter().collect()
    }

    /// One past the largest frame index (0 for an empty table).
    pub fn frame_end(&self) -> usize {
        self.points
            .iter()
            .map(|p| p.frame.saturating_add(1))
            .max()
            .unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rows written field by field are the bytes serde wrote: every flag, non-finite
    /// and extreme values, names that need quoting, random values from a fixed seed.
    #[test]
    fn csv_bytes_are_what_serde_writes() {
        let mut state = 0x853c_49e6_748f_ea9b_u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let names = [
            "0",
            "p17",
            "a,b",
            "say \"hi\"",
            "two\nlines",
            " ",
            "ü",
            "",
            "cr\r",
            "tab\t",
            "#x",
            "a-b_c.d",
        ];
        let flags = [PointFlag::Detected, PointFlag::Split, PointFlag::Interpolated];
        let specials = [
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.0,
            -0.0,
            1e-7,
            1e300,
            5e-324,
        ];
        let mut points = Vec::new();
        for k in 0..500usize {
            let mut value = || match next() % 4 {
                0 => specials[(next() % specials.len() as u64) as usize],
                1 => (next() >> 11) as f64 / (1u64 << 53) as f64 * 512.0,
                2 => f64::from_bits(next()),
                _ => (next() % 1000) as f64,
            };
            points.push(TrackPoint {
                frame: if k % 50 == 0 { usize::MAX - k } else { k },
                particle: names[k % names.len()].to_string(),
                x: value(),
                y: value(),
                mass: value(),
                size: value(),
                ep: value(),
                flag: flags[k % 3],
            });
        }
        let table = TrackTable { points };
        // The row as serde writes it once rounded: the mass as `f32` where that holds it.
        #[derive(Serialize)]
        #[serde(untagged)]
        enum Mass {
            Single(f32),
            Double(f64),
        }
        #[derive(Serialize)]
        struct Row<'a> {
            frame: usize,
            particle: &'a str,
            x: f64,
            y: f64,
            mass: Mass,
            size: f64,
            ep: f64,
            flag: PointFlag,
        }
        let mut w = csv::Writer::from_writer(Vec::new());
        for p in &table.points {
            w.serialize(Row {
                frame: p.frame,
                particle: &p.particle,
                x: p.x,
                y: p.y,
                mass: single(p.mass).map_or(Mass::Double(p.mass), Mass::Single),
                size: to_micro_px(p.size),
                ep: to_micro_px(p.ep),
                flag: p.flag,
            })
            .unwrap();
        }
        assert_eq!(table.csv_bytes().unwrap(), w.into_inner().unwrap());
        let empty = TrackTable::default().csv_bytes().unwrap();
        assert_eq!(empty, b"frame,particle,x,y,mass,size,ep,flag\n");
    }

    #[test]
    fn written_rows_hold_positions_whole_sizes_to_a_micro_pixel_and_mass_to_single() {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut uniform = move |scale: f64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * scale
        };
        let points: Vec<TrackPoint> = (0..2000)
            .map(|k| TrackPoint {
                mass: uniform(1e6),
                size: uniform(60.0),
                ep: uniform(0.1),
                ..TrackPoint::new(k, "p0", uniform(4096.0) - 100.0, uniform(4096.0))
            })
            .collect();
        let table = TrackTable { points };
        let bytes = table.csv_bytes().unwrap();
        let back = TrackTable::read_from(&bytes[..], Path::new("t.csv")).unwrap();
        for (a, b) in table.points.iter().zip(&back.points) {
            assert_eq!((a.x, a.y), (b.x, b.y));
            for (u, v) in [(a.size, b.size), (a.ep, b.ep)] {
                assert!((u - v).abs() <= 5.000_001e-7, "{u} written as {v}");
            }
            // Half an f32 step, and the shortest decimal that reads back as that f32.
            assert!(
                (a.mass - b.mass).abs() <= a.mass * 1.2e-7,
                "{} as {}",
                a.mass,
                b.mass
            );
        }
        // Whole micro-pixels in sizes and errors, and the file a fifth shorter than at full
        // precision (84 bytes a row here against 106).
        let text = String::from_utf8(bytes).unwrap();
        for line in text.lines().skip(1) {
            let fields: Vec<&str> = line.split(',').collect();
            for f in [fields[5], fields[6]] {
                let micro = f.parse::<f64>().unwrap() * 1e6;
                assert!((micro - micro.round()).abs() < 1e-3, "{f} in {line}");
            }
        }
        let mut full = csv::Writer::from_writer(Vec::new());
        for p in &table.points {
            full.serialize(p).unwrap();
        }
        let full = full.into_inner().unwrap().len();
        assert!(5 * text.len() < 4 * full, "{} bytes against {full}", text.len());
    }

    #[test]
    fn reads_truth_columns_and_extra_columns() {
        let text = "frame,particle,x,y,extra\n0,p0,1.5,2.5,z\n1,p0,2.0,3.0,z\n";
        let t = TrackTable::read_from(text.as_bytes(), Path::new("t.csv")).unwrap();
        assert_eq!(t.points.len(), 2);
        assert_eq!(t.points[1].frame, 1);
        assert!((t.points[1].y - 3.0).abs() < 1e-12);
        assert!(t.points[0].mass.is_nan());
        assert_eq!(t.points[0].flag, PointFlag::Detected);
    }

    #[test]
    fn error_names_file_line_and_column() {
        let text = "frame,particle,x,y\n0,p0,1.5,2.5\n1,p0,abc,3.0\n";
        let e = TrackTable::read_from(text.as_bytes(), Path::new("bad.csv"))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("bad.csv:3:"), "{e}");
        assert!(e.contains("`x`"), "{e}");
    }

    #[test]
    fn missing_column_is_named() {
        let e = TrackTable::read_from("frame,particle,x\n".as_bytes(), Path::new("t.csv"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing column `y`"), "{e}");
    }

    #[test]
    fn non_finite_position_is_an_error() {
        let text = "frame,particle,x,y\n0,p0,NaN,2.5\n";
        let e = TrackTable::read_from(text.as_bytes(), Path::new("t.csv"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("t.csv:2") && e.contains("non-finite"), "{e}");
    }

    #[test]
    fn an_empty_table_keeps_its_header() {
        let dir = std::env::temp_dir().join(format!("physfit-tt-empty-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.csv");
        TrackTable::default().write_csv(&path).unwrap();
        assert!(TrackTable::read_csv(&path).unwrap().points.is_empty());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn round_trip_through_csv() {
        let dir = std::env::temp_dir().join(format!("physfit-tt-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.csv");
        let mut p = TrackPoint::new(3, "a", 1.25, -2.5);
        p.flag = PointFlag::Interpolated;
        p.mass = 10.0;
        let t = TrackTable { points: vec![p] };
        t.write_csv(&path).unwrap();
        let back = TrackTable::read_csv(&path).unwrap();
        assert_eq!(back.points[0].flag, PointFlag::Interpolated);
        assert_eq!(back.points[0].particle, "a");
        assert!(back.points[0].size.is_nan());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
