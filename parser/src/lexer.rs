//! A streaming tokenizer for pbrt-v3 scene text.
//!
//! The input is read through a fixed window (1 MiB by default) that is refilled
//! at token boundaries, so a 100 MB `trianglemesh` never sits in memory as text:
//! only the parsed numbers do. Tokens are recognised with nom's *streaming*
//! parsers: when a token runs into the end of the window they report
//! `Incomplete`, the window is refilled (keeping the partial token) and the
//! token is recognised again. At end of input the *complete* variants are used.
//!
//! Token rules follow pbrt-v3's tokenizer: whitespace is space, tab, CR, LF;
//! `#` at the start of a token comments to the end of the line; `[` and `]` are
//! tokens of their own; a `"` string may not contain a raw newline and supports
//! the escapes `\b \f \n \r \t \\ \' \"`; anything else runs up to whitespace,
//! a quote or a bracket.

use crate::diag::FileLoc;
use nom::error::{ErrorKind, ParseError};
use nom::{IResult, Parser};
use std::io::Read;
use std::sync::Arc;

/// Default size of the read window.
pub(crate) const CHUNK: usize = 1 << 20;
/// No single token (a quoted string, a bare word) may be longer than this.
const MAX_TOKEN: usize = 64 << 20;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    /// A bare word: a directive name or a number.
    Bare,
    /// A quoted string.
    Str,
    LBracket,
    RBracket,
    Eof,
}

/// Why a token could not be recognised.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LexFail {
    pub msg: &'static str,
}

impl<'a> ParseError<&'a [u8]> for LexFail {
    fn from_error_kind(_: &'a [u8], _: ErrorKind) -> Self {
        LexFail { msg: "unexpected input" }
    }
    fn append(_: &'a [u8], _: ErrorKind, other: Self) -> Self {
        other
    }
}

/// Bytes that end a bare token (pbrt-v3: whitespace, a quote or a bracket).
static DELIM: [bool; 256] = {
    let mut t = [false; 256];
    t[b' ' as usize] = true;
    t[b'\t' as usize] = true;
    t[b'\r' as usize] = true;
    t[b'\n' as usize] = true;
    t[b'"' as usize] = true;
    t[b'[' as usize] = true;
    t[b']' as usize] = true;
    t
};

#[inline]
fn is_delim(b: u8) -> bool {
    DELIM[b as usize]
}

/// A bare token: one or more non-delimiter bytes.
#[inline]
fn bare<const STREAMING: bool>(i: &[u8]) -> IResult<&[u8], &[u8], LexFail> {
    if STREAMING {
        nom::bytes::streaming::take_till1(is_delim).parse(i)
    } else {
        nom::bytes::complete::take_till1(is_delim).parse(i)
    }
}

/// A quoted string including its quotes; the flag says whether it holds escapes.
fn quoted<const STREAMING: bool>(i: &[u8]) -> IResult<&[u8], (&[u8], bool), LexFail> {
    let (_, _) = nom::bytes::complete::tag::<_, _, LexFail>(&b"\""[..]).parse(i)?;
    let mut k = 1;
    let mut escaped = false;
    loop {
        match memchr::memchr3(b'"', b'\\', b'\n', &i[k..]) {
            None => {
                return if STREAMING {
                    Err(nom::Err::Incomplete(nom::Needed::Unknown))
                } else {
                    Err(nom::Err::Failure(LexFail { msg: "unterminated string at end of file" }))
                };
            }
            Some(off) => {
                let at = k + off;
                match i[at] {
                    b'"' => return Ok((&i[at + 1..], (&i[..at + 1], escaped))),
                    b'\n' => {
                        return Err(nom::Err::Failure(LexFail {
                            msg: "unterminated string: newline inside a quoted string",
                        }))
                    }
                    _ => {
                        escaped = true;
                        if at + 1 >= i.len() {
                            return if STREAMING {
                                Err(nom::Err::Incomplete(nom::Needed::new(1)))
                            } else {
                                Err(nom::Err::Failure(LexFail { msg: "premature end of file after '\\' in a string" }))
                            };
                        }
                        k = at + 2;
                    }
                }
            }
        }
    }
}

#[inline]
/// One token at the start of `i` (no leading whitespace): its kind, length and escape flag.
fn token<const STREAMING: bool>(i: &[u8]) -> IResult<&[u8], (Kind, usize, bool), LexFail> {
    match i.first() {
        None => Err(nom::Err::Incomplete(nom::Needed::new(1))),
        Some(b'[') => Ok((&i[1..], (Kind::LBracket, 1, false))),
        Some(b']') => Ok((&i[1..], (Kind::RBracket, 1, false))),
        Some(b'"') => quoted::<STREAMING>.map(|(s, e): (&[u8], bool)| (Kind::Str, s.len(), e)).parse(i),
        Some(_) => bare::<STREAMING>.map(|s: &[u8]| (Kind::Bare, s.len(), false)).parse(i),
    }
}

/// Decodes a quoted token (with its quotes) into its text.
pub(crate) fn decode_string(tok: &[u8], escaped: bool) -> Result<String, &'static str> {
    let inner = &tok[1..tok.len() - 1];
    if !escaped {
        return Ok(crate::diag::escape_lossy(inner));
    }
    let mut out = Vec::with_capacity(inner.len());
    let mut it = inner.iter();
    while let Some(&b) = it.next() {
        if b != b'\\' {
            out.push(b);
            continue;
        }
        let c = match it.next() {
            Some(b'b') => 8,
            Some(b'f') => 12,
            Some(b'n') => b'\n',
            Some(b'r') => b'\r',
            Some(b't') => b'\t',
            Some(b'\\') => b'\\',
            Some(b'\'') => b'\'',
            Some(b'"') => b'"',
            _ => {
                return Err("unexpected escaped character in string (pbrt-v3 allows \\b \\f \\n \\r \\t \\\\ \\' \\\")")
            }
        };
        out.push(c);
    }
    Ok(crate::diag::escape_lossy(&out))
}

/// Number of UTF-8 characters (non-continuation bytes) in `b`.
#[inline]
fn count_chars(b: &[u8]) -> u32 {
    b.iter().filter(|&&c| (c & 0xC0) != 0x80).count() as u32
}

pub(crate) struct Lexer {
    reader: Option<Box<dyn Read>>,
    buf: Vec<u8>,
    /// Window size to refill to; grows only for tokens longer than the window.
    window: usize,
    pos: usize,
    eof: bool,
    /// Absolute offset of `buf[0]` in the input.
    base: u64,
    line: u32,
    /// Absolute offset of the first byte of the current line.
    line_start: u64,
    /// Column cache: `col_chars` characters lie between `line_start` and absolute offset `col_off`.
    col_off: u64,
    col_chars: u32,
    in_comment: bool,
    /// The pending (peeked, not consumed) token.
    tok: Option<(Kind, usize, usize, bool)>,
    pub file: Arc<str>,
}

impl Lexer {
    /// A lexer over text held in memory.
    pub fn from_bytes(bytes: Vec<u8>, file: Arc<str>) -> Lexer {
        let window = bytes.len().max(1);
        Lexer::new(None, bytes, window, true, file)
    }

    /// A lexer that streams from `reader` through a window of `window` bytes.
    pub fn from_reader(reader: Box<dyn Read>, file: Arc<str>, window: usize) -> Lexer {
        Lexer::new(Some(reader), Vec::with_capacity(window), window.max(16), false, file)
    }

    fn new(reader: Option<Box<dyn Read>>, buf: Vec<u8>, window: usize, eof: bool, file: Arc<str>) -> Lexer {
        Lexer {
            reader,
            buf,
            window,
            pos: 0,
            eof,
            base: 0,
            line: 1,
            line_start: 0,
            col_off: 0,
            col_chars: 0,
            in_comment: false,
            tok: None,
            file,
        }
    }

    /// Advances the column cache to buffer index `p` (which must be on the current line).
    fn column_at(&mut self, p: usize) -> u32 {
        let a = self.base + p as u64;
        if self.col_off < self.line_start || self.col_off > a {
            if self.line_start < self.base {
                // The line start left the window and the cache is ahead: best effort.
                return self.col_chars + 1;
            }
            self.col_off = self.line_start;
            self.col_chars = 0;
        }
        let from = (self.col_off - self.base) as usize;
        self.col_chars += count_chars(&self.buf[from..p]);
        self.col_off = a;
        self.col_chars + 1
    }

    fn refill(&mut self) -> Result<(), String> {
        let Some(reader) = self.reader.as_mut() else {
            self.eof = true;
            return Ok(());
        };
        // Carry the column count over the bytes about to be dropped.
        let p = self.pos;
        let a = self.base + p as u64;
        if self.col_off < self.line_start {
            self.col_off = self.line_start;
            self.col_chars = 0;
        }
        if self.col_off < a {
            let from = (self.col_off.max(self.base) - self.base) as usize;
            self.col_chars += count_chars(&self.buf[from..p]);
            self.col_off = a;
        }
        self.buf.drain(..p);
        self.base = a;
        self.pos = 0;
        if self.buf.len() >= self.window {
            if self.window >= MAX_TOKEN {
                return Err(format!("token longer than {} MiB", MAX_TOKEN >> 20));
            }
            self.window *= 2;
        }
        let old = self.buf.len();
        self.buf.resize(self.window, 0);
        let mut filled = old;
        while filled < self.window {
            match reader.read(&mut self.buf[filled..]) {
                Ok(0) => {
                    self.eof = true;
                    break;
                }
                Ok(n) => filled += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => {
                    self.buf.truncate(filled);
                    return Err(format!("read error: {e}"));
                }
            }
        }
        self.buf.truncate(filled);
        if self.eof {
            self.reader = None;
        }
        Ok(())
    }

    /// The kind of the next token, reading more input as needed. On error, the
    /// message and the location of the offending token.
    pub fn peek(&mut self) -> Result<Kind, (String, FileLoc)> {
        if let Some((k, ..)) = self.tok {
            return Ok(k);
        }
        loop {
            if self.in_comment {
                match memchr::memchr2(b'\n', b'\r', &self.buf[self.pos..]) {
                    Some(k) => {
                        self.pos += k;
                        self.in_comment = false;
                    }
                    None => {
                        self.pos = self.buf.len();
                        if self.eof {
                            self.in_comment = false;
                        } else {
                            let l = self.here();
                            self.refill().map_err(|m| (m, l))?;
                        }
                        continue;
                    }
                }
            }
            let buf = &self.buf;
            let mut p = self.pos;
            while p < buf.len() {
                match buf[p] {
                    b' ' | b'\t' | b'\r' => p += 1,
                    b'\n' => {
                        p += 1;
                        self.line += 1;
                        self.line_start = self.base + p as u64;
                    }
                    _ => break,
                }
            }
            self.pos = p;
            if p == self.buf.len() {
                if self.eof {
                    self.tok = Some((Kind::Eof, p, p, false));
                    return Ok(Kind::Eof);
                }
                let l = self.here();
                self.refill().map_err(|m| (m, l))?;
                continue;
            }
            if self.buf[p] == b'#' {
                self.in_comment = true;
                continue;
            }
            let r = if self.eof { token::<false>(&self.buf[p..]) } else { token::<true>(&self.buf[p..]) };
            match r {
                Ok((_, (kind, len, esc))) => {
                    self.tok = Some((kind, p, p + len, esc));
                    return Ok(kind);
                }
                Err(nom::Err::Incomplete(_)) => {
                    let l = self.here();
                    self.refill().map_err(|m| (m, l))?;
                }
                Err(nom::Err::Error(e)) | Err(nom::Err::Failure(e)) => {
                    return Err((e.msg.to_string(), self.here()));
                }
            }
        }
    }

    /// Location of the current position (the pending token's start after `peek`).
    pub fn here(&mut self) -> FileLoc {
        let p = self.tok.map(|t| t.1).unwrap_or(self.pos);
        let col = self.column_at(p);
        FileLoc::new(self.file.clone(), self.line, col)
    }

    /// The bytes of the pending token (call after `peek`).
    #[inline]
    pub fn text(&self) -> &[u8] {
        match self.tok {
            Some((_, s, e, _)) => &self.buf[s..e],
            None => &[],
        }
    }

    /// The decoded text of the pending string token.
    pub fn string(&self) -> Result<String, &'static str> {
        match self.tok {
            Some((Kind::Str, s, e, esc)) => decode_string(&self.buf[s..e], esc),
            _ => Err("expected a quoted string"),
        }
    }

    #[inline]
    pub fn consume(&mut self) {
        if let Some((_, _, e, _)) = self.tok.take() {
            self.pos = e;
        }
    }

    /// The text of the current line if it is entirely in the window.
    pub fn current_line_text(&self) -> Option<String> {
        if self.line_start < self.base {
            return None;
        }
        let s = (self.line_start - self.base) as usize;
        let from = self.tok.map(|t| t.1).unwrap_or(self.pos).max(s).min(self.buf.len());
        let end = match memchr::memchr(b'\n', &self.buf[from..]) {
            Some(k) => from + k,
            None if self.eof => self.buf.len(),
            None => return None,
        };
        let mut line = &self.buf[s..end];
        if line.last() == Some(&b'\r') {
            line = &line[..line.len() - 1];
        }
        Some(String::from_utf8_lossy(line).into_owned())
    }

    pub fn line(&self) -> u32 {
        self.line
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// All tokens of `text` as (kind, text) pairs, read through a window of `window` bytes.
    fn lex(text: &str, window: usize) -> Result<Vec<(Kind, String)>, String> {
        let mut l = Lexer::from_reader(Box::new(std::io::Cursor::new(text.as_bytes().to_vec())), "t".into(), window);
        let mut out = vec![];
        loop {
            let k = l.peek().map_err(|e| e.0)?;
            if k == Kind::Eof {
                return Ok(out);
            }
            let t = if k == Kind::Str {
                l.string().map_err(|e| e.to_string())?
            } else {
                String::from_utf8_lossy(l.text()).into()
            };
            out.push((k, t));
            l.consume();
        }
    }

    #[test]
    fn tokens_comments_brackets_and_escapes() {
        let src = "Shape \"sphere\" # a comment \"x\" [\n\"float radius\"[-5e-51 .5 +1 1. 1e+3]\"a\\\"b\\\\c\\n\"";
        for window in [16, 17, 23, 1 << 20] {
            let toks = lex(src, window).unwrap();
            let texts: Vec<&str> = toks.iter().map(|t| t.1.as_str()).collect();
            assert_eq!(
                texts,
                ["Shape", "sphere", "float radius", "[", "-5e-51", ".5", "+1", "1.", "1e+3", "]", "a\"b\\c\n"],
                "window {window}"
            );
            assert_eq!(toks[3].0, Kind::LBracket);
            assert_eq!(toks[9].0, Kind::RBracket);
        }
    }

    #[test]
    fn comment_at_eof_and_hash_inside_bare_token() {
        assert_eq!(lex("A#b c # tail", 1 << 20).unwrap().len(), 2);
        assert_eq!(lex("# only a comment", 16).unwrap().len(), 0);
        // A comment longer than the window is skipped across refills.
        let long = format!("#{}\nWorldBegin", "x".repeat(100));
        assert_eq!(lex(&long, 16).unwrap(), vec![(Kind::Bare, "WorldBegin".to_string())]);
    }

    #[test]
    fn string_errors() {
        assert!(lex("\"abc", 1 << 20).unwrap_err().contains("end of file"));
        assert!(lex("\"abc", 16).unwrap_err().contains("end of file"));
        assert!(lex("\"ab\nc\"", 1 << 20).unwrap_err().contains("newline"));
        assert!(lex("\"a\\qb\"", 1 << 20).unwrap_err().contains("escaped"));
        assert!(lex("\"a\\", 1 << 20).unwrap_err().contains("end of file"));
    }

    #[test]
    fn long_tokens_grow_the_window() {
        let s = format!("\"{}\" x", "y".repeat(1000));
        let toks = lex(&s, 16).unwrap();
        assert_eq!(toks[0].1.len(), 1000);
        assert_eq!(toks[1].1, "x");
    }

    #[test]
    fn locations_are_line_and_character_column() {
        let src = "a\n  bé \"c\"\n\td";
        for window in [4, 1 << 20] {
            let mut l = Lexer::from_reader(Box::new(std::io::Cursor::new(src.as_bytes().to_vec())), "f".into(), window);
            let mut locs = vec![];
            while l.peek().unwrap() != Kind::Eof {
                let h = l.here();
                locs.push((h.line, h.column));
                l.consume();
            }
            assert_eq!(locs, [(1, 1), (2, 3), (2, 6), (3, 2)], "window {window}");
        }
    }

    #[test]
    fn current_line_text_strips_cr() {
        let mut l = Lexer::from_bytes(b"a\r\nbb cc\r\n".to_vec(), "f".into());
        l.peek().unwrap();
        l.consume();
        l.peek().unwrap();
        assert_eq!(l.current_line_text().unwrap(), "bb cc");
    }
}
