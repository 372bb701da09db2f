//! Small helpers for writing the report's Markdown.

/// A GitHub-flavoured Markdown table: `header` names the columns, each row gives one cell per column (missing
/// cells are left empty). Columns whose cells are all numbers (`2.01`, `-1e-3`, `12 %`, `2.01 ± 0.03`) are
/// right-aligned. `|` and line breaks inside cells are escaped so that a cell can never break the table.
pub fn markdown_table(header: &[&str], rows: &[Vec<String>]) -> String {
    let cell = |s: &str| s.replace('|', "\\|").replace(['\n', '\r'], " ");
    let numeric = |col: usize| {
        let mut cells = rows
            .iter()
            .filter_map(|r| r.get(col))
            .map(|c| c.trim())
            .filter(|c| !c.is_empty())
            .peekable();
        cells.peek().is_some() && cells.all(looks_numeric)
    };
    let mut out = String::new();
    out.push('|');
    for name in header {
        out.push_str(&format!(" {} |", cell(name)));
    }
    out.push_str("\n|");
    for col in 0..header.len() {
        out.push_str(if numeric(col) { "---:|" } else { "---|" });
    }
    out.push('\n');
    for row in rows {
        out.push('|');
        for col in 0..header.len() {
            out.push_str(&format!(" {} |", cell(row.get(col).map_or("", String::as_str))));
        }
        out.push('\n');
    }
    out
}

/// True if and only if `cell` reads as a number, possibly with a sign, exponent, `%` or `±` part (e.g. `-1.5e-3`,
/// `12 %`, `2.01 ± 0.03`).
fn looks_numeric(cell: &str) -> bool {
    let first = cell.split(['±', ' ']).next().unwrap_or("");
    first.trim_end_matches('%').parse::<f64>().is_ok()
}

/// A Markdown image `![alt](file)` for a picture beside the report; `(`, `)`, spaces and `%` in the file name are
/// escaped so that any name links correctly (and [`super::markdown_to_html_page`] finds it again).
pub fn markdown_image(alt: &str, file: &str) -> String {
    let alt = alt.replace(['[', ']'], "").replace('\n', " ");
    let mut dest = String::with_capacity(file.len());
    for c in file.chars() {
        match c {
            '%' => dest.push_str("%25"),
            ' ' => dest.push_str("%20"),
            '(' => dest.push_str("%28"),
            ')' => dest.push_str("%29"),
            c => dest.push(c),
        }
    }
    format!("![{alt}]({dest})")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_aligns_numbers_right_and_escapes_pipes() {
        let rows = vec![
            vec!["S".to_owned(), "2.00".to_owned(), "a|b".to_owned()],
            vec!["T".to_owned(), "-1e-3".to_owned()],
        ];
        let table = markdown_table(&["name", "value", "note"], &rows);
        assert_eq!(
            table,
            "| name | value | note |\n|---|---:|---|\n| S | 2.00 | a\\|b |\n| T | -1e-3 |  |\n"
        );
    }

    #[test]
    fn image_names_with_spaces_and_percent_round_trip_through_html() {
        let dir = tempfile::tempdir().unwrap();
        let name = "cost (100% run).png";
        crate::report::write_png(&dir.path().join(name), &image::RgbImage::new(2, 2)).unwrap();
        let md = markdown_image("cost [log]", name);
        assert_eq!(md, "![cost log](cost%20%28100%25%20run%29.png)");
        let html = crate::report::markdown_to_html_page(&md, "t", dir.path()).unwrap();
        assert!(html.contains("src=\"data:image/png;base64,"), "{html}");
    }
}
