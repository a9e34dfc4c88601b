//! The Markdown report: a header plus an ordered list of [`Section`]s, each with its own
//! tables and plot references, so that other parts (e.g. the accuracy section) can be
//! appended in order before [`Report::write`].

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::BenchError;

/// Column alignment in a Markdown table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Align {
    Left,
    Right,
}

/// A Markdown (GitHub pipe) table.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Table {
    header: Vec<(String, Align)>,
    rows: Vec<Vec<String>>,
}

impl Table {
    /// A table with these columns; the first is left-aligned, the others right-aligned
    /// (names first, numbers after). Use [`Table::align`] to change one.
    pub fn new<S: Into<String>>(columns: impl IntoIterator<Item = S>) -> Table {
        let header = columns
            .into_iter()
            .enumerate()
            .map(|(i, c)| (c.into(), if i == 0 { Align::Left } else { Align::Right }))
            .collect();
        Table { header, rows: Vec::new() }
    }

    /// Set the alignment of column `i`.
    pub fn align(mut self, i: usize, align: Align) -> Table {
        self.header[i].1 = align;
        self
    }

    /// Append a row; missing cells are left empty, extra cells are an error of the caller
    /// and are dropped.
    pub fn row<S: Into<String>>(&mut self, cells: impl IntoIterator<Item = S>) {
        let mut r: Vec<String> = cells.into_iter().map(Into::into).take(self.header.len()).collect();
        r.resize(self.header.len(), String::new());
        self.rows.push(r);
    }

    /// Number of rows (without the header).
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// True when the table has no rows.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// The table as Markdown, one line per row, ending with a newline. Pipes and line
    /// breaks inside cells are escaped so they cannot break the table.
    pub fn to_markdown(&self) -> String {
        let cell = |s: &str| s.replace('|', "\\|").replace(['\n', '\r'], " ");
        let mut out = String::new();
        let line = |out: &mut String, cells: &mut dyn Iterator<Item = String>| {
            out.push('|');
            for c in cells {
                out.push(' ');
                out.push_str(&c);
                out.push_str(" |");
            }
            out.push('\n');
        };
        line(&mut out, &mut self.header.iter().map(|(h, _)| cell(h)));
        line(
            &mut out,
            &mut self.header.iter().map(|(_, a)| match a {
                Align::Left => "---".to_string(),
                Align::Right => "---:".to_string(),
            }),
        );
        for r in &self.rows {
            line(&mut out, &mut r.iter().map(|c| cell(c)));
        }
        out
    }
}

/// One section of the report: a `##` title and its Markdown body.
#[derive(Clone, Debug, PartialEq)]
pub struct Section {
    pub title: String,
    pub markdown: String,
}

impl Section {
    pub fn new(title: impl Into<String>, markdown: impl Into<String>) -> Section {
        Section { title: title.into(), markdown: markdown.into() }
    }
}

/// The whole report: a title, a header (machine, versions, command line) and sections in order.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    pub title: String,
    pub header: String,
    pub sections: Vec<Section>,
    /// Image files (plots) the sections reference, relative to the report's folder.
    pub files: Vec<PathBuf>,
}

impl Report {
    /// The report as one Markdown document.
    pub fn to_markdown(&self) -> String {
        let mut out = format!("# {}\n\n{}\n", self.title, self.header.trim_end());
        for s in &self.sections {
            let _ = write!(out, "\n## {}\n\n{}\n", s.title, s.markdown.trim_end());
        }
        out
    }

    /// Write `report.md` into `dir` (which must exist: the plots are already there);
    /// returns its path.
    pub fn write(&self, dir: &Path) -> Result<PathBuf, BenchError> {
        let path = dir.join(REPORT_FILE);
        std::fs::write(&path, self.to_markdown()).map_err(|source| BenchError::Write { path: path.clone(), source })?;
        Ok(path)
    }
}

/// File name of the Markdown report in the output folder.
pub const REPORT_FILE: &str = "report.md";

/// A number with `digits` decimals, or "n/a" for a non-finite one.
pub fn num(x: f64, digits: usize) -> String {
    if x.is_finite() {
        format!("{x:.digits$}")
    } else {
        "n/a".to_string()
    }
}

/// An integer with thousands separators (`1,234,567`).
pub fn count(n: u64) -> String {
    let s = n.to_string();
    // Leading group of 1 to 3 digits, then groups of exactly 3.
    let head = match s.len() % 3 {
        0 => 3,
        r => r,
    }
    .min(s.len());
    let mut out = s[..head].to_string();
    for k in (head..s.len()).step_by(3) {
        out.push(',');
        out.push_str(&s[k..k + 3]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_markdown_has_header_alignment_and_escaped_cells() {
        let mut t = Table::new(["scene", "ms"]).align(1, Align::Right);
        t.row(["a|b", "1.50"]);
        t.row(["short"]);
        assert_eq!(t.len(), 2);
        assert_eq!(t.to_markdown(), "| scene | ms |\n| --- | ---: |\n| a\\|b | 1.50 |\n| short |  |\n");
    }

    #[test]
    fn report_puts_sections_in_order() {
        let r = Report {
            title: "T".into(),
            header: "head\n".into(),
            sections: vec![Section::new("One", "1"), Section::new("Two", "2\n")],
            files: vec![],
        };
        assert_eq!(r.to_markdown(), "# T\n\nhead\n\n## One\n\n1\n\n## Two\n\n2\n");
    }

    #[test]
    fn number_formats() {
        assert_eq!(num(1.23456, 2), "1.23");
        assert_eq!(num(f64::INFINITY, 2), "n/a");
        assert_eq!(count(0), "0");
        assert_eq!(count(999), "999");
        assert_eq!(count(1000), "1,000");
        assert_eq!(count(1234567), "1,234,567");
    }
}
