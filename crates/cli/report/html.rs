//! `report.html`: the report's Markdown as ONE self-contained HTML page.
//!
//! Every picture the Markdown shows is read from the report directory and inlined as a `data:` URI, so the page
//! can be mailed or archived alone. The page loads nothing else: no stylesheet, script or font files, and raw HTML
//! in the Markdown is shown as text rather than passed through (it could load anything).

use std::path::Path;

use anyhow::Context;
use base64::Engine;
use pulldown_cmark::{CowStr, Event, Options, Parser, Tag, TagEnd};

/// The page's stylesheet: small, inline, and using only fonts every system has.
const STYLE: &str = "\
body{font-family:system-ui,-apple-system,'Segoe UI',Roboto,'DejaVu Sans',sans-serif;line-height:1.5;color:#1b1b1b;\
background:#fff;margin:0}\
main{max-width:62rem;margin:0 auto;padding:1.5rem 2rem 3rem}\
h1,h2,h3{line-height:1.25;margin:1.6em 0 .5em}h1{font-size:1.8rem;margin-top:.5em}\
h2{font-size:1.35rem;border-bottom:1px solid #ddd;padding-bottom:.2em}h3{font-size:1.1rem}\
table{border-collapse:collapse;margin:1em 0;font-size:.92rem}\
th,td{border:1px solid #ccc;padding:.3em .7em;text-align:left;vertical-align:top}\
th{background:#f2f2f2}tr:nth-child(even) td{background:#fafafa}\
code{font-family:ui-monospace,'DejaVu Sans Mono',Menlo,Consolas,monospace;font-size:.9em;background:#f4f4f4;\
padding:.1em .3em;border-radius:3px}\
pre{background:#f4f4f4;padding:.8em 1em;overflow-x:auto;border-radius:4px}pre code{padding:0;background:none}\
img{max-width:100%;height:auto;display:block;margin:.8em 0}\
blockquote{margin:1em 0;padding:.2em 1em;border-left:4px solid #ccc;color:#444}";

/// Converts the report's Markdown (headings, tables, code blocks, lists, images) into one HTML page titled
/// `title`, with a small inline stylesheet and every `![alt](file)` image read from `base_dir` (the directory
/// holding the Markdown) and inlined as a `data:` URI (PNG, JPEG or GIF, recognised by content).
///
/// Links to web addresses (`http:`, `https:`, `mailto:`) and to anchors in the page are kept; links to files are
/// replaced by their text, since the page carries no files with it. Raw HTML in the Markdown is escaped.
///
/// # Errors
/// An image that cannot be read, is not a PNG/JPEG/GIF, or is a web address, gives an error naming it.
pub fn markdown_to_html_page(markdown: &str, title: &str, base_dir: &Path) -> anyhow::Result<String> {
    let options = Options::ENABLE_TABLES | Options::ENABLE_STRIKETHROUGH;
    let mut events: Vec<Event<'_>> = Vec::new();
    // One entry per open link: true if it was dropped (a link to a file), so its end is dropped too.
    let mut open_links: Vec<bool> = Vec::new();
    for event in Parser::new_ext(markdown, options) {
        match event {
            Event::Start(Tag::Image {
                link_type,
                dest_url,
                title,
                id,
            }) => {
                let dest_url = CowStr::from(inline_image(&dest_url, base_dir)?);
                events.push(Event::Start(Tag::Image {
                    link_type,
                    dest_url,
                    title,
                    id,
                }));
            }
            Event::Start(Tag::Link {
                link_type,
                dest_url,
                title,
                id,
            }) => {
                let keep = is_web_or_anchor(&dest_url);
                open_links.push(!keep);
                if keep {
                    events.push(Event::Start(Tag::Link {
                        link_type,
                        dest_url,
                        title,
                        id,
                    }));
                }
            }
            Event::End(TagEnd::Link) => {
                if !open_links.pop().unwrap_or(false) {
                    events.push(Event::End(TagEnd::Link));
                }
            }
            // Shown as text, quotes escaped too, so no attribute of it survives in the page.
            Event::Html(raw) | Event::InlineHtml(raw) => events.push(Event::Html(escape_html(&raw).into())),
            other => events.push(other),
        }
    }
    let mut body = String::with_capacity(markdown.len() * 2);
    pulldown_cmark::html::push_html(&mut body, events.into_iter());
    Ok(format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n<main>\n{body}</main>\n</body>\n</html>\n",
        escape_html(title)
    ))
}

/// True if and only if `url` is a web address or an anchor in the page (a link the page may keep).
fn is_web_or_anchor(url: &str) -> bool {
    let lower = url.to_ascii_lowercase();
    url.starts_with('#')
        || ["http://", "https://", "mailto:"]
            .iter()
            .any(|s| lower.starts_with(s))
}

/// The `data:` URI of the image at `url` (relative to `base_dir`), or the URL itself if it already is one.
fn inline_image(url: &str, base_dir: &Path) -> anyhow::Result<String> {
    if url.starts_with("data:") {
        return Ok(url.to_owned());
    }
    anyhow::ensure!(
        !url.contains("://"),
        "image {url} is a web address; report.html inlines every picture, so it must be a file beside the report"
    );
    let path = base_dir.join(percent_decode(url));
    let bytes = std::fs::read(&path)
        .with_context(|| format!("reading image {} for the HTML report", path.display()))?;
    let mime = image_mime(&bytes).with_context(|| {
        format!(
            "image {} for the HTML report is not a PNG, JPEG or GIF file",
            path.display()
        )
    })?;
    let encoded = base64::engine::general_purpose::STANDARD.encode(&bytes);
    Ok(format!("data:{mime};base64,{encoded}"))
}

/// The MIME type of an image recognised by its first bytes.
fn image_mime(bytes: &[u8]) -> Option<&'static str> {
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        Some("image/png")
    } else if bytes.starts_with(&[0xff, 0xd8, 0xff]) {
        Some("image/jpeg")
    } else if bytes.starts_with(b"GIF87a") || bytes.starts_with(b"GIF89a") {
        Some("image/gif")
    } else {
        None
    }
}

/// Decodes `%XX` escapes in a Markdown link destination (e.g. `%20` for a space); malformed escapes stay as written.
fn percent_decode(url: &str) -> String {
    let bytes = url.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |b: u8| (b as char).to_digit(16);
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            if let (Some(h), Some(l)) = (hex(bytes[i + 1]), hex(bytes[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// `text` with the five HTML-special characters escaped.
fn escape_html(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The values of every `name="..."` attribute in `html`.
    fn attributes<'a>(html: &'a str, name: &str) -> Vec<&'a str> {
        let needle = format!("{name}=\"");
        html.match_indices(&needle)
            .map(|(at, _)| {
                let rest = &html[at + needle.len()..];
                &rest[..rest.find('"').unwrap_or(rest.len())]
            })
            .collect()
    }

    /// Asserts that `html` loads nothing from outside itself.
    fn assert_self_contained(html: &str) {
        let lower = html.to_ascii_lowercase();
        for src in attributes(&lower, "src") {
            assert!(src.starts_with("data:"), "external src {src}");
        }
        assert!(!lower.contains("src='"), "single-quoted src");
        for href in attributes(&lower, "href") {
            assert!(
                href.starts_with('#') || href.starts_with("https://"),
                "href to a file: {href}"
            );
        }
        assert!(!lower.contains("<link"), "a <link> element");
        assert!(!lower.contains("<script"), "a <script> element");
        assert!(!lower.contains("url("), "a CSS url()");
        assert!(!lower.contains("@import"), "a CSS @import");
    }

    fn write_png(dir: &Path, name: &str, w: u32, h: u32) -> Vec<u8> {
        let image = image::RgbImage::from_pixel(w, h, image::Rgb([10, 200, 30]));
        crate::report::write_png(&dir.join(name), &image).unwrap();
        std::fs::read(dir.join(name)).unwrap()
    }

    const REPORT: &str = "# Lab note: pendulum\n\n\
        Fitted with `springs + gravity`; see [the JSON](report.json) and [section](#residuals).\n\n\
        | parameter | truth | fitted | error |\n|---|---:|---:|---:|\n| S (px/s²) | 2.00 | 2.01 | 0.5 % |\n\n\
        ## Residuals\n\n![residuals before and after](residuals.png)\n\n\
        - first item\n- second item\n\n```text\nphysfit run --seed 7\n```\n\n\
        <img src=\"http://example.invalid/x.png\"><script>alert(1)</script>\n\n\
        More at <https://example.invalid/docs>.\n";

    #[test]
    fn page_is_self_contained_with_tables_headings_and_inlined_pictures() {
        let dir = tempfile::tempdir().unwrap();
        let png = write_png(dir.path(), "residuals.png", 5, 3);
        let html = markdown_to_html_page(REPORT, "physfit <report>", dir.path()).unwrap();
        assert_self_contained(&html);
        assert!(html.contains("<title>physfit &lt;report&gt;</title>"));
        assert!(html.contains("<h1>Lab note: pendulum</h1>") && html.contains("<h2>Residuals</h2>"));
        assert!(html.contains("<table>") && html.contains("<th>parameter</th>"));
        assert!(
            html.contains("<td style=\"text-align: right\">2.01</td>"),
            "right-aligned numbers"
        );
        assert!(html.contains("<li>first item</li>") && html.contains("physfit run --seed 7"));
        // The picture is the very PNG beside the report, base64-encoded.
        let srcs = attributes(&html, "src");
        assert_eq!(srcs.len(), 1, "{srcs:?}");
        let data = srcs[0]
            .strip_prefix("data:image/png;base64,")
            .expect("a PNG data URI");
        assert_eq!(
            base64::engine::general_purpose::STANDARD.decode(data).unwrap(),
            png
        );
        assert!(html.contains("alt=\"residuals before and after\""));
        // The link to a file became plain text; the anchor and the web link stay.
        assert!(
            html.contains("see the JSON and <a href=\"#residuals\">section</a>"),
            "{html}"
        );
        assert!(html.contains("href=\"https://example.invalid/docs\""));
        // Raw HTML is shown as text, never executed or loaded.
        assert!(
            html.contains("&lt;img src=&quot;http://example.invalid/x.png&quot;&gt;&lt;script&gt;"),
            "{html}"
        );
    }

    #[test]
    fn unreadable_image_is_an_error_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let err = markdown_to_html_page("![x](missing-chart.png)\n", "t", dir.path()).unwrap_err();
        let text = format!("{err:#}");
        assert!(text.contains("missing-chart.png"), "{text}");
        std::fs::write(dir.path().join("notes.png"), b"not a picture").unwrap();
        let text = format!(
            "{:#}",
            markdown_to_html_page("![x](notes.png)", "t", dir.path()).unwrap_err()
        );
        assert!(text.contains("notes.png") && text.contains("not a PNG"), "{text}");
        let text = format!(
            "{:#}",
            markdown_to_html_page("![x](https://e.invalid/a.png)", "t", dir.path()).unwrap_err()
        );
        assert!(text.contains("https://e.invalid/a.png"), "{text}");
    }

    #[test]
    fn percent_escaped_image_names_are_found() {
        let dir = tempfile::tempdir().unwrap();
        write_png(dir.path(), "cost history.png", 2, 2);
        let html = markdown_to_html_page("![c](cost%20history.png)", "t", dir.path()).unwrap();
        assert_self_contained(&html);
        assert!(html.contains("src=\"data:image/png;base64,"));
    }

    #[test]
    fn percent_decoding_leaves_malformed_escapes() {
        assert_eq!(percent_decode("a%20b%2"), "a b%2");
        assert_eq!(percent_decode("%zz%41"), "%zzA");
    }
}
