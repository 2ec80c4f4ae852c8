//! The page's HTML: the blocks in order, inline CSS, and the table sorter.

use std::fmt::Write;

use super::{Block, Cell, Figure, Table};

/// Text made safe inside HTML elements and double-quoted attributes.
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

const STYLE: &str = r#"
body { font: 14px/1.4 system-ui, -apple-system, "Segoe UI", sans-serif; margin: 1.5em; color: #222; }
h1 { font-size: 1.5em; margin: 0 0 .5em; }
h2 { font-size: 1.2em; margin: 1.6em 0 .4em; border-bottom: 1px solid #ddd; }
p { max-width: 70em; }
table.report { border-collapse: collapse; margin: .5em 0 1em; font-variant-numeric: tabular-nums; }
table.report caption { text-align: left; font-weight: 600; padding: .3em 0; }
table.report th, table.report td { border: 1px solid #ccc; padding: .2em .5em; text-align: right; }
table.report th { background: #f0f0f0; cursor: pointer; user-select: none; position: sticky; top: 0; }
table.report th[data-type="text"], table.report td.t { text-align: left; }
table.report th[aria-sort="ascending"]::after { content: " \25B2"; }
table.report th[aria-sort="descending"]::after { content: " \25BC"; }
tr.bad td, td.bad { background: #fbd5d5; }
tr.warn td, td.warn { background: #fdf0c8; }
tr.good td, td.good { background: #d9f2d9; }
.figures { display: grid; grid-template-columns: repeat(auto-fill, minmax(360px, 1fr)); gap: 12px; }
figure { margin: 0; padding: 6px; border: 2px solid #ddd; background: #fafafa; }
figure.bad { border-color: #d33; }
figure.good { border-color: #3a3; }
figure.warn { border-color: #d90; }
figure img { width: 100%; height: auto; image-rendering: pixelated; display: block; }
figcaption { font-size: 12px; margin-top: 4px; }
figcaption b { font-size: 13px; }
.legend { display: flex; flex-wrap: wrap; gap: .4em 1.2em; margin: .4em 0 .8em; font-size: 13px; }
.legend span.sw { display: inline-block; width: 1em; height: 1em; border: 1px solid #888;
  vertical-align: -.15em; margin-right: .3em; }
"#;

/// Sorts a table by the clicked column: numbers by `data-key` (or the text), missing values last, ties in
/// their current order; a second click reverses.
const SCRIPT: &str = r#"
document.querySelectorAll("table.report th").forEach(function (th) {
  th.addEventListener("click", function () {
    var table = th.closest("table"), body = table.tBodies[0];
    var col = Array.prototype.indexOf.call(th.parentNode.children, th);
    var num = th.dataset.type === "num";
    var asc = th.getAttribute("aria-sort") !== "ascending";
    table.querySelectorAll("th").forEach(function (h) { h.removeAttribute("aria-sort"); });
    th.setAttribute("aria-sort", asc ? "ascending" : "descending");
    function key(tr) {
      var td = tr.cells[col];
      var k = td.hasAttribute("data-key") ? td.getAttribute("data-key") : td.textContent.trim();
      if (k === "") return null;
      if (!num) return k;
      var v = parseFloat(k);
      return isNaN(v) ? null : v;
    }
    var rows = Array.prototype.map.call(body.rows, function (tr, i) { return [key(tr), i, tr]; });
    rows.sort(function (a, b) {
      if (a[0] === null || b[0] === null) {
        return (a[0] === null) - (b[0] === null) || a[1] - b[1];
      }
      var c = num ? a[0] - b[0] : a[0].localeCompare(b[0]);
      return (asc ? c : -c) || a[1] - b[1];
    });
    rows.forEach(function (r) { body.appendChild(r[2]); });
  });
});
"#;

/// The whole page.
pub(super) fn page(title: &str, blocks: &[Block]) -> String {
    let mut s = String::new();
    let t = escape(title);
    let _ = write!(
        s,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"generator\" content=\"ogm-corners {}\">\n<title>{t}</title>\n<style>{STYLE}</style>\n\
         </head>\n<body>\n<h1>{t}</h1>\n",
        env!("CARGO_PKG_VERSION")
    );
    for b in blocks {
        match b {
            Block::Heading(h) => {
                let _ = writeln!(s, "<h2>{}</h2>", escape(h));
            }
            Block::Text(p) => {
                let _ = writeln!(s, "<p>{}</p>", escape(p));
            }
            Block::Table(table) => write_table(&mut s, table),
            Block::Figures(figures, min_width) => {
                let _ = writeln!(
                    s,
                    "<div class=\"figures\" style=\"grid-template-columns: repeat(auto-fill, minmax(min({min_width}px, 100%), 1fr))\">"
                );
                for f in figures {
                    write_figure(&mut s, f);
                }
                s.push_str("</div>\n");
            }
            Block::Legend(entries) => {
                s.push_str("<div class=\"legend\">");
                for (label, [r, g, b]) in entries {
                    let _ = write!(
                        s,
                        "<span><span class=\"sw\" style=\"background:rgb({r},{g},{b})\"></span>{}</span>",
                        escape(label)
                    );
                }
                s.push_str("</div>\n");
            }
        }
    }
    let _ = write!(s, "<script>{SCRIPT}</script>\n</body>\n</html>\n");
    s
}

fn write_table(s: &mut String, t: &Table) {
    let _ = write!(
        s,
        "<table class=\"report\" id=\"{}\" data-rows=\"{}\">\n<caption>{}</caption>\n<thead><tr>",
        escape(&t.id),
        t.rows.len(),
        escape(&t.caption)
    );
    for (label, numeric) in &t.columns {
        let kind = if *numeric { "num" } else { "text" };
        let _ = write!(s, "<th data-type=\"{kind}\">{}</th>", escape(label));
    }
    s.push_str("</tr></thead>\n<tbody>\n");
    for row in &t.rows {
        match row.class {
            Some(c) => {
                let _ = write!(s, "<tr class=\"{c}\">");
            }
            None => s.push_str("<tr>"),
        }
        for (cell, (_, numeric)) in row.cells.iter().zip(&t.columns) {
            write_cell(s, cell, *numeric);
        }
        s.push_str("</tr>\n");
    }
    s.push_str("</tbody>\n</table>\n");
}

fn write_cell(s: &mut String, c: &Cell, numeric: bool) {
    s.push_str("<td");
    // Text columns are left-aligned (`t`), whatever other class a cell has.
    match (c.class, numeric) {
        (Some(c), true) => {
            let _ = write!(s, " class=\"{c}\"");
        }
        (Some(c), false) => {
            let _ = write!(s, " class=\"t {c}\"");
        }
        (None, false) => s.push_str(" class=\"t\""),
        (None, true) => {}
    }
    if let Some(k) = &c.key {
        let _ = write!(s, " data-key=\"{}\"", escape(k));
    }
    s.push('>');
    match &c.link {
        Some(href) => {
            let _ = write!(s, "<a href=\"{}\">{}</a>", escape(href), escape(&c.text));
        }
        None => s.push_str(&escape(&c.text)),
    }
    s.push_str("</td>");
}

fn write_figure(s: &mut String, f: &Figure) {
    s.push_str("<figure");
    if let Some(id) = &f.id {
        let _ = write!(s, " id=\"{}\"", escape(id));
    }
    if let Some(c) = f.class {
        let _ = write!(s, " class=\"{c}\"");
    }
    let alt = f.caption.first().map(String::as_str).unwrap_or("");
    let _ = write!(
        s,
        "><img src=\"{}\" width=\"{}\" height=\"{}\" alt=\"{}\"><figcaption>",
        escape(&f.src),
        f.size.0,
        f.size.1,
        escape(alt)
    );
    for (i, line) in f.caption.iter().enumerate() {
        if i == 0 {
            let _ = write!(s, "<b>{}</b>", escape(line));
        } else {
            let _ = write!(s, "<br>{}", escape(line));
        }
    }
    s.push_str("</figcaption></figure>\n");
}
