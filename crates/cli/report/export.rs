//! The report formats: one [`Exporter`] per file, all fed the same [`ReportDocument`].

use std::path::{Path, PathBuf};

use anyhow::Context;

/// The content of one report: the Markdown lab note, its machine-readable summary, and where its pictures are.
#[derive(Debug, Clone, PartialEq)]
pub struct ReportDocument {
    /// Title of the report (the HTML page's `<title>`).
    pub title: String,
    /// The lab note in Markdown; its images are file names relative to `dir`.
    pub markdown: String,
    /// The machine-readable summary written as `report.json`.
    pub json: serde_json::Value,
    /// The report directory: where the pictures already are and where the report files are written.
    pub dir: PathBuf,
}

/// One report format: turns a [`ReportDocument`] into the bytes of one file in the report directory.
pub trait Exporter {
    /// The file name this format is written to, e.g. `"report.md"`.
    fn file_name(&self) -> &'static str;

    /// The file's complete contents.
    ///
    /// # Errors
    /// When the document cannot be expressed in this format (e.g. a picture of an HTML page cannot be read).
    fn serialize(&self, doc: &ReportDocument) -> anyhow::Result<Vec<u8>>;
}

/// `report.md`: the Markdown as written, pictures as files beside it.
#[derive(Debug, Clone, Copy, Default)]
pub struct MarkdownExporter;

impl Exporter for MarkdownExporter {
    fn file_name(&self) -> &'static str {
        "report.md"
    }

    fn serialize(&self, doc: &ReportDocument) -> anyhow::Result<Vec<u8>> {
        let mut text = doc.markdown.clone();
        if !text.ends_with('\n') {
            text.push('\n');
        }
        Ok(text.into_bytes())
    }
}

/// `report.html`: one self-contained page, pictures inlined ([`super::markdown_to_html_page`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct HtmlExporter;

impl Exporter for HtmlExporter {
    fn file_name(&self) -> &'static str {
        "report.html"
    }

    fn serialize(&self, doc: &ReportDocument) -> anyhow::Result<Vec<u8>> {
        super::markdown_to_html_page(&doc.markdown, &doc.title, &doc.dir).map(String::into_bytes)
    }
}

/// `report.json`: the summary, pretty-printed.
#[derive(Debug, Clone, Copy, Default)]
pub struct JsonExporter;

impl Exporter for JsonExporter {
    fn file_name(&self) -> &'static str {
        "report.json"
    }

    fn serialize(&self, doc: &ReportDocument) -> anyhow::Result<Vec<u8>> {
        let mut bytes = serde_json::to_vec_pretty(&doc.json)?;
        bytes.push(b'\n');
        Ok(bytes)
    }
}

/// Writes `doc` in each of `exporters`' formats into `doc.dir` (atomically, one file each) and returns the paths
/// written. Every format is serialised before any file is written, so a failure leaves no mix of old and new files.
///
/// # Errors
/// The first format that fails, or a file that cannot be written, named in the message.
pub fn write_reports(doc: &ReportDocument, exporters: &[&dyn Exporter]) -> anyhow::Result<Vec<PathBuf>> {
    let mut outputs = Vec::with_capacity(exporters.len());
    for exporter in exporters {
        let path = doc.dir.join(exporter.file_name());
        let bytes = exporter
            .serialize(doc)
            .with_context(|| format!("preparing {}", path.display()))?;
        outputs.push((path, bytes));
    }
    for (path, bytes) in &outputs {
        write(path, bytes)?;
    }
    Ok(outputs.into_iter().map(|(path, _)| path).collect())
}

fn write(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    physfit_model::write_atomic(path, bytes).with_context(|| format!("writing {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_formats_carry_the_same_report() {
        let dir = tempfile::tempdir().unwrap();
        crate::report::write_png(&dir.path().join("cost.png"), &image::RgbImage::new(3, 3)).unwrap();
        let doc = ReportDocument {
            title: "physfit report".into(),
            markdown: "# Fit\n\n![cost](cost.png)\n\n| k | cost |\n|---|---|\n| 1 | 0.5 |".into(),
            json: serde_json::json!({ "cost": 0.5 }),
            dir: dir.path().to_path_buf(),
        };
        let written = write_reports(&doc, &[&MarkdownExporter, &HtmlExporter, &JsonExporter]).unwrap();
        let names: Vec<_> = written
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, ["report.md", "report.html", "report.json"]);
        let md = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
        assert!(md.starts_with("# Fit") && md.ends_with('\n'));
        let html = std::fs::read_to_string(dir.path().join("report.html")).unwrap();
        assert!(
            html.contains("<h1>Fit</h1>") && html.contains("<td>0.5</td>") && html.contains("data:image/png")
        );
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap()).unwrap();
        assert!((json["cost"].as_f64().unwrap() - 0.5).abs() < 1e-12);
    }

    #[test]
    fn a_failing_format_writes_no_file_and_names_the_picture() {
        let dir = tempfile::tempdir().unwrap();
        let doc = ReportDocument {
            title: "t".into(),
            markdown: "![cost](gone.png)".into(),
            json: serde_json::json!({}),
            dir: dir.path().to_path_buf(),
        };
        let err = write_reports(&doc, &[&MarkdownExporter, &HtmlExporter]).unwrap_err();
        let text = format!("{err:#}");
        assert!(
            text.contains("report.html") && text.contains("gone.png"),
            "{text}"
        );
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            0,
            "report.md was written anyway"
        );
    }
}
