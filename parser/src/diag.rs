//! Located diagnostics (errors and warnings) in the style of rustc.

use std::collections::HashSet;
use std::fmt;
use std::sync::{Arc, Mutex};

/// A position in a scene file: `file:line:column`, 1-based.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct FileLoc {
    /// The file as the user named it (or `<embedded>`/`<command line>` for in-memory text).
    pub file: Arc<str>,
    pub line: u32,
    pub column: u32,
}

impl FileLoc {
    pub fn new(file: Arc<str>, line: u32, column: u32) -> Self {
        FileLoc { file, line, column }
    }
    /// The location of things nobody wrote (pbrt-v3's defaults).
    pub fn builtin() -> Self {
        FileLoc { file: Arc::from("<default>"), line: 0, column: 0 }
    }
    /// The location of values given on the command line (shown as `<command line>`).
    pub fn command_line() -> Self {
        FileLoc { file: Arc::from("<command line>"), line: 0, column: 0 }
    }
    pub fn is_builtin(&self) -> bool {
        self.line == 0
    }
}

impl fmt::Display for FileLoc {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_builtin() {
            write!(f, "{}", self.file)
        } else {
            write!(f, "{}:{}:{}", self.file, self.line, self.column)
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Severity {
    Error,
    Warning,
}

/// An error or warning, optionally located, with the offending source line
/// and a caret under the column when the source is available.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Diagnostic {
    pub severity: Severity,
    pub message: String,
    pub loc: Option<FileLoc>,
    /// The source line at `loc`, captured when the diagnostic was made.
    pub source_line: Option<String>,
    /// Extra `= note:` lines.
    pub notes: Vec<String>,
}

impl Diagnostic {
    pub fn error(loc: Option<FileLoc>, message: impl Into<String>) -> Self {
        Diagnostic { severity: Severity::Error, message: message.into(), loc, source_line: None, notes: vec![] }
    }
    pub fn warning(loc: Option<FileLoc>, message: impl Into<String>) -> Self {
        Diagnostic { severity: Severity::Warning, message: message.into(), loc, source_line: None, notes: vec![] }
    }
    pub fn is_error(&self) -> bool {
        self.severity == Severity::Error
    }
    /// Fills `source_line` from the file (or the [`crate::parse_str`] text) at `loc`,
    /// for diagnostics raised after parsing (unused parameters, bad indices…).
    pub fn with_source(mut self) -> Self {
        if self.source_line.is_none() {
            if let Some(loc) = &self.loc {
                self.source_line = crate::source_line(loc);
            }
        }
        self
    }
}

/// `bytes` as text, with every byte that is not valid UTF-8 written `\xNN` (pbrt-v3's strings are
/// bytes; a message must show them, not U+FFFD or raw bytes in a terminal).
pub fn escape_lossy(bytes: &[u8]) -> String {
    let mut out = String::with_capacity(bytes.len());
    for chunk in bytes.utf8_chunks() {
        out.push_str(chunk.valid());
        for b in chunk.invalid() {
            out.push_str(&format!("\\x{b:02x}"));
        }
    }
    out
}

/// A control character (but a newline) as an escape, anything else as itself.
fn visible(c: char) -> std::borrow::Cow<'static, str> {
    match c {
        '\n' => "\n".into(),
        c if c.is_control() && (c as u32) < 0x100 => format!("\\x{:02x}", c as u32).into(),
        c if c.is_control() => format!("\\u{{{:x}}}", c as u32).into(),
        c => c.to_string().into(),
    }
}

fn escape_controls(s: &str) -> String {
    s.chars().map(visible).collect()
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let tag = match self.severity {
            Severity::Error => "error",
            Severity::Warning => "warning",
        };
        writeln!(f, "{tag}: {}", escape_controls(&self.message))?;
        if let Some(loc) = &self.loc {
            let gutter = " ".repeat(loc.line.to_string().len());
            writeln!(f, "{gutter}--> {loc}")?;
            if let Some(line) = &self.source_line {
                // Tabs would misplace the caret: show them as single spaces.
                let chars: Vec<char> = line.chars().map(|c| if c == '\t' { ' ' } else { c }).collect();
                let mut col = (loc.column as usize).saturating_sub(1).min(chars.len());
                // Long lines (a mesh on one line) are shown as a window around the column.
                const HALF: usize = 60;
                let (from, to) = (col.saturating_sub(HALF), (col + HALF).min(chars.len()));
                // Control characters are shown escaped; the caret moves with them.
                let width = |cs: &[char]| cs.iter().map(|&c| visible(c).chars().count()).sum::<usize>();
                let mut shown: String = chars[from..to].iter().map(|&c| visible(c)).collect();
                col = width(&chars[from..col]);
                if from > 0 {
                    shown.insert_str(0, "...");
                    col += 3;
                }
                if to < chars.len() {
                    shown.push_str("...");
                }
                writeln!(f, "{gutter} |")?;
                writeln!(f, "{} | {}", loc.line, shown)?;
                writeln!(f, "{gutter} | {}^", " ".repeat(col))?;
            }
        }
        for n in &self.notes {
            writeln!(f, "  = note: {}", escape_controls(n))?;
        }
        Ok(())
    }
}

/// A thread-safe collector of warnings that keeps each distinct one once, in order, and the
/// render's live status line (what a progress bar shows beside its count: e.g. how many shading
/// points took a fallback path so far).
#[derive(Default, Debug)]
pub struct DiagSink {
    inner: Mutex<(Vec<Diagnostic>, HashSet<Diagnostic>)>,
    status: Mutex<Option<String>>,
}

impl DiagSink {
    pub fn new() -> Self {
        Self::default()
    }
    pub fn push(&self, d: Diagnostic) {
        let mut g = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        if g.1.insert(d.clone()) {
            g.0.push(d);
        }
    }
    pub fn warn(&self, loc: Option<FileLoc>, message: impl Into<String>) {
        self.push(Diagnostic::warning(loc, message));
    }
    pub fn extend(&self, ds: impl IntoIterator<Item = Diagnostic>) {
        for d in ds {
            self.push(d);
        }
    }
    pub fn take(&self) -> Vec<Diagnostic> {
        let mut g = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        g.1.clear();
        std::mem::take(&mut g.0)
    }
    pub fn snapshot(&self) -> Vec<Diagnostic> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner()).0.clone()
    }
    pub fn len(&self) -> usize {
        self.inner.lock().unwrap_or_else(|e| e.into_inner()).0.len()
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Replaces the live status line (not a warning: not kept, not deduplicated).
    pub fn set_status(&self, s: impl Into<String>) {
        *self.status.lock().unwrap_or_else(|e| e.into_inner()) = Some(s.into());
    }
    /// The live status line, if a render set one.
    pub fn status(&self) -> Option<String> {
        self.status.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }
}
