//! A small HTML page builder for offline reports: headings, paragraphs, tables, lists, rows of
//! figures and collapsible sections, with the stylesheet inlined. No script, no external
//! resource: a page and the PNGs beside it (linked by relative paths) are the whole report,
//! so a folder can be zipped, mailed or opened from disk. Text is escaped; the output is a
//! pure function of the calls (deterministic).

use std::fmt::Write as _;
use std::path::Path;

/// Escapes text for HTML element content and quoted attribute values.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
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

/// How a table cell or list item is marked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mark {
    /// Plain.
    None,
    /// A passing figure (green).
    Pass,
    /// A failing figure (red).
    Fail,
    /// Not applicable / missing (grey).
    Muted,
}

impl Mark {
    fn class(self) -> &'static str {
        match self {
            Mark::None => "",
            Mark::Pass => " class=\"pass\"",
            Mark::Fail => " class=\"fail\"",
            Mark::Muted => " class=\"muted\"",
        }
    }
}

/// A table cell.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Cell {
    /// Text (escaped on output).
    pub text: String,
    /// Marking.
    pub mark: Mark,
}

impl Cell {
    /// A plain cell.
    pub fn new(text: impl Into<String>) -> Cell {
        Cell {
            text: text.into(),
            mark: Mark::None,
        }
    }

    /// A marked cell.
    pub fn marked(text: impl Into<String>, mark: Mark) -> Cell {
        Cell {
            text: text.into(),
            mark,
        }
    }
}

/// An image with a caption. `src` is relative to the page.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Figure {
    /// Relative path of the PNG (forward slashes).
    pub src: String,
    /// Caption (also the `alt` text).
    pub caption: String,
    /// Displayed width in CSS pixels (the file may be larger or smaller).
    pub display_width: u32,
    /// Enlarge without smoothing (small rasters: each pixel stays a square).
    pub pixelated: bool,
}

impl Figure {
    /// A figure shown `display_width` CSS pixels wide.
    pub fn new(src: impl Into<String>, caption: impl Into<String>, display_width: u32) -> Figure {
        Figure {
            src: src.into(),
            caption: caption.into(),
            display_width,
            pixelated: false,
        }
    }

    /// Shown with nearest-neighbour enlargement.
    pub fn pixelated(mut self) -> Figure {
        self.pixelated = true;
        self
    }
}

const STYLE: &str = "body{font-family:sans-serif;margin:1.5em auto;max-width:1500px;padding:0 1em;color:#222}\
h1{font-size:1.5em}h2{font-size:1.25em;border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:2em}\
h3{font-size:1.05em}table{border-collapse:collapse;margin:.6em 0}\
th,td{border:1px solid #ccc;padding:.25em .6em;text-align:left;font-size:.9em}\
th{background:#f2f2f2}td.num{text-align:right}.pass{color:#0a7a2f;font-weight:bold}\
.fail{color:#b3121d;font-weight:bold}.muted{color:#888}\
.figs{display:flex;flex-wrap:wrap;gap:.8em;align-items:flex-start;margin:.5em 0}\
figure{margin:0}figcaption{font-size:.8em;color:#444;max-width:100%}\
img{border:1px solid #ddd;height:auto;max-width:100%}img.px{image-rendering:pixelated}\
details{margin:.6em 0}summary{cursor:pointer;font-weight:bold}code{font-size:.9em}\
.legend span{display:inline-block;margin-right:1.2em}";

/// An HTML page under construction.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Page {
    title: String,
    body: String,
}

impl Page {
    /// An empty page with a `<title>` and an `<h1>`.
    pub fn new(title: &str) -> Page {
        let mut p = Page {
            title: title.to_string(),
            body: String::new(),
        };
        p.heading(1, title, None);
        p
    }

    /// `<hN id=..>`; `level` is clamped to 1–6.
    pub fn heading(&mut self, level: u8, text: &str, id: Option<&str>) {
        let l = level.clamp(1, 6);
        let id = id.map_or(String::new(), |i| format!(" id=\"{}\"", escape(i)));
        let _ = writeln!(self.body, "<h{l}{id}>{}</h{l}>", escape(text));
    }

    /// A paragraph of text.
    pub fn paragraph(&mut self, text: &str) {
        let _ = writeln!(self.body, "<p>{}</p>", escape(text));
    }

    /// A paragraph whose parts are text or `<code>`: `(text, is_code)`.
    pub fn paragraph_parts(&mut self, parts: &[(&str, bool)]) {
        self.body.push_str("<p>");
        for (t, code) in parts {
            if *code {
                let _ = write!(self.body, "<code>{}</code>", escape(t));
            } else {
                self.body.push_str(&escape(t));
            }
        }
        self.body.push_str("</p>\n");
    }

    /// A colour legend: `(CSS colour, label)` pairs.
    pub fn legend(&mut self, items: &[(&str, &str)]) {
        self.body.push_str("<p class=\"legend\">");
        for (colour, label) in items {
            let _ = write!(
                self.body,
                "<span><span style=\"color:{}\">&#9679;</span> {}</span>",
                escape(colour),
                escape(label)
            );
        }
        self.body.push_str("</p>\n");
    }

    /// A link to `href` (relative or a fragment `#id`).
    pub fn link(&mut self, href: &str, text: &str) {
        let _ = writeln!(
            self.body,
            "<p><a href=\"{}\">{}</a></p>",
            escape(href),
            escape(text)
        );
    }

    /// A bulleted list; each item with its mark.
    pub fn list(&mut self, items: &[Cell]) {
        self.body.push_str("<ul>\n");
        for c in items {
            let _ = writeln!(self.body, "<li{}>{}</li>", c.mark.class(), escape(&c.text));
        }
        self.body.push_str("</ul>\n");
    }

    /// A table with a header row.
    pub fn table(&mut self, headers: &[&str], rows: &[Vec<Cell>]) {
        self.body.push_str("<table>\n<tr>");
        for h in headers {
            let _ = write!(self.body, "<th>{}</th>", escape(h));
        }
        self.body.push_str("</tr>\n");
        for r in rows {
            self.body.push_str("<tr>");
            for c in r {
                let _ = write!(self.body, "<td{}>{}</td>", c.mark.class(), escape(&c.text));
            }
            self.body.push_str("</tr>\n");
        }
        self.body.push_str("</table>\n");
    }

    /// A wrapping row of figures.
    pub fn figures(&mut self, figs: &[Figure]) {
        self.body.push_str("<div class=\"figs\">\n");
        for f in figs {
            let _ = writeln!(
                self.body,
                "<figure style=\"width:{w}px\"><img src=\"{src}\" alt=\"{cap}\" width=\"{w}\"{px}><figcaption>{cap}</figcaption></figure>",
                w = f.display_width,
                src = escape(&f.src),
                cap = escape(&f.caption),
                px = if f.pixelated { " class=\"px\"" } else { "" },
            );
        }
        self.body.push_str("</div>\n");
    }

    /// A collapsible section; `fill` adds its content.
    pub fn details(&mut self, summary: &str, open: bool, fill: impl FnOnce(&mut Page)) {
        let _ = writeln!(
            self.body,
            "<details{}><summary>{}</summary>",
            if open { " open" } else { "" },
            escape(summary)
        );
        fill(self);
        self.body.push_str("</details>\n");
    }

    /// The whole document.
    pub fn render(&self) -> String {
        format!(
            "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n{}</body>\n</html>\n",
            escape(&self.title),
            self.body
        )
    }

    /// Writes the document to `path`.
    pub fn write(&self, path: &Path) -> std::io::Result<()> {
        std::fs::write(path, self.render())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_and_links_relative_images() {
        let mut p = Page::new("a <b> & \"c\"");
        p.table(
            &["x"],
            &[
                vec![Cell::marked("<script>", Mark::Fail)],
                vec![Cell::new("1")],
            ],
        );
        p.figures(&[Figure::new("e/v_real.png", "real 'a'", 320).pixelated()]);
        p.details("more", false, |p| p.paragraph("inside"));
        let html = p.render();
        assert!(html.contains("<title>a &lt;b&gt; &amp; &quot;c&quot;</title>"));
        assert!(html.contains("<td class=\"fail\">&lt;script&gt;</td>"));
        assert!(html
            .contains("src=\"e/v_real.png\" alt=\"real &#39;a&#39;\" width=\"320\" class=\"px\""));
        assert!(html.contains("<details><summary>more</summary>\n<p>inside</p>\n</details>"));
        assert!(!html.contains("<script>"));
    }
}
