//! G-code text to a [`Program`] of SI motion blocks.
//!
//! The syntax (words, comments, line numbers) is read by the `gcode` crate; this module gives the
//! words their meaning, keeps the modal state, converts to metres and seconds, checks every arc,
//! and reports the first problem with its line and column ([`NcError`]). It never panics.
//!
//! # The accepted language
//!
//! A block (one line) holds words: a letter and a number (`X12.5`, `G1`, `F500`). Comments are
//! written in parentheses (closed on the same line) or after `;` to the end of the line; an `N`
//! line number and an `O` program number are allowed and ignored, as are `%` delimiters and blank
//! lines. Letters are case-insensitive. A letter may appear once per block.
//!
//! | words | meaning |
//! |---|---|
//! | `G0` | rapid positioning (modal) |
//! | `G1` | straight line at the feed (modal) |
//! | `G2` / `G3` | clockwise / counter-clockwise arc, or helix, at the feed (modal), seen from the positive end of the plane's normal |
//! | `G4 P` | dwell for `P` **seconds** (as LinuxCNC, `G4 P1.5` = 1.5 s; note that Fanuc's `P` counts milliseconds) |
//! | `G17` / `G18` / `G19` | arc plane XY / ZX / YZ (default G17) |
//! | `G20` / `G21` | inches / millimetres (default G21); applies to the whole block it appears in |
//! | `G90` / `G91` | absolute / incremental X, Y, Z (default G90) |
//! | `G94` | feed per minute: the only feed mode, accepted for compatibility |
//! | `X Y Z` | end point (absolute or incremental) |
//! | `I J K` | arc centre offset from the arc's start point, always incremental (G91.1 style) |
//! | `R` | arc radius instead of I/J/K: `R > 0` the shorter arc (≤ 180°), `R < 0` the longer one |
//! | `F` | feed, mm/min (in/min after G20), modal, > 0 |
//! | `S` | spindle speed, rpm, 0 to 200 000 (the fastest production spindles) |
//! | `M3` / `M4` / `M5` | spindle clockwise / counter-clockwise / stop |
//! | `M2`, `M30` | end of program: the blocks after it are not read |
//!
//! A full circle is a `G2`/`G3` with I/J/K whose end point equals its start point in the plane
//! (within [`FULL_CIRCLE_TOLERANCE_M`]; the parser then sets the end exactly to the start). The
//! start and end of an arc must lie at the same distance from its centre within
//! [`RADIUS_TOLERANCE_M`] (0.001 mm). Within a block, the units, plane and distance mode are set
//! first, then the feed, the spindle speed and the spindle state, then the dwell or motion; the
//! spindle state of a block is the one in force after its M3/M4/M5.
//!
//! The machine starts in G17, G21, G90, with no motion mode (axis words before the first G0, G1,
//! G2 or G3 are refused), no feed (a G1, G2 or G3 before the first `F` is refused) and the
//! spindle stopped at 0 rpm.

use super::program::{ArcDirection, Block, Motion, Plane, Program, SourceSpan, Spindle};
use gcode::core::{
    BlockVisitor, CommandVisitor, ControlFlow, HasDiagnostics, Number, ProgramVisitor, Span,
    TokenType, Value,
};
use nalgebra::Vector3;
use std::borrow::Cow;
use thiserror::Error;

/// The G codes the parser accepts.
pub const SUPPORTED_G_CODES: &str = "G0, G1, G2, G3, G4, G17, G18, G19, G20, G21, G90, G91, G94";
/// The M codes the parser accepts.
pub const SUPPORTED_M_CODES: &str = "M2, M3, M4, M5, M30";
/// The largest accepted difference between an arc's start and end radius, m (0.001 mm).
pub const RADIUS_TOLERANCE_M: f64 = 1e-6;
/// An arc whose end is this close to its start in the plane (m) is a full circle.
pub const FULL_CIRCLE_TOLERANCE_M: f64 = 1e-9;

const WORD_LETTERS: &str = "G, M, N, X, Y, Z, I, J, K, R, F, S and P";
const BLOCK_GRAMMAR: &str = "a block holds words (a letter and a number, as X12.5 or G1), \
                             comments in parentheses or after ;, and an N line number";
const MM_PER_INCH: f64 = 25.4;
/// The fastest spindle speed accepted, rpm: above the fastest production spindles (about
/// 150 000 rpm, micro-machining), so that a typo cannot ask for a cut step of picoseconds.
pub const MAX_SPINDLE_RPM: f64 = 200_000.0;

/// A G-code program the parser refused: where (1-based line and column), and what is wrong and
/// what would be accepted.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
#[error("line {line}, column {column}: {message}")]
pub struct NcError {
    /// Line, 1-based.
    pub line: usize,
    /// Column, 1-based, in characters.
    pub column: usize,
    /// What is wrong and what is accepted.
    pub message: String,
}

/// Parses G-code `text` into a [`Program`] whose tool starts at `start` (m, absolute).
///
/// Units in the result are SI: positions in m, feeds in m/s, dwells in s. See the module docs
/// for the accepted words. The first problem found in reading order is returned as an
/// [`NcError`]; any input, however malformed, gives `Ok` or `Err`, never a panic.
pub fn parse(text: &str, start: Vector3<f64>) -> Result<Program, NcError> {
    // A byte-order mark (Windows editors write one) is not part of the program; columns are
    // counted as an editor shows them, without it.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let locator = Locator::new(text);
    if !start.iter().all(|c| c.is_finite()) {
        return Err(NcError {
            line: 1,
            column: 1,
            message: format!("the start position {start:?} m is not finite"),
        });
    }
    let (blocks, mut faults) = scan(text);
    faults.sort_by_key(|f| f.offset);
    let mut machine = Interpreter::new(start, &locator);
    let mut pending = faults.into_iter().peekable();
    for (k, raw) in blocks.iter().enumerate() {
        let next_start = blocks.get(k + 1).map_or(usize::MAX, |b| b.start);
        if let Some(f) = pending.next_if(|f| f.offset < next_start) {
            return Err(locator.error(f));
        }
        match machine.block(raw) {
            Ok(Flow::Continue) => {}
            Ok(Flow::End) => return Ok(machine.finish()),
            Err(f) => return Err(locator.error(f)),
        }
    }
    match pending.next() {
        Some(f) => Err(locator.error(f)),
        None => Ok(machine.finish()),
    }
}

// ---------------------------------------------------------------------------------------------
// Locating byte offsets

/// A problem at a byte offset of the source.
#[derive(Clone, Debug)]
struct Fault {
    offset: usize,
    message: String,
}

impl Fault {
    fn new(offset: usize, message: impl Into<String>) -> Self {
        Fault {
            offset,
            message: message.into(),
        }
    }
}

/// Byte offset to line and column.
struct Locator<'s> {
    src: &'s str,
    line_starts: Vec<usize>,
}

impl<'s> Locator<'s> {
    fn new(src: &'s str) -> Self {
        let line_starts = std::iter::once(0)
            .chain(src.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        Locator { src, line_starts }
    }

    fn span(&self, offset: usize) -> SourceSpan {
        let line = self.line_starts.partition_point(|&s| s <= offset).max(1);
        let line_start = self.line_starts.get(line - 1).copied().unwrap_or(0);
        let column = self
            .src
            .get(line_start..offset.min(self.src.len()))
            .map_or(0, |s| s.chars().count())
            + 1;
        SourceSpan { line, column }
    }

    fn error(&self, fault: Fault) -> NcError {
        let SourceSpan { line, column } = self.span(fault.offset);
        // The parser reads `X1e2` as X1 followed by a word E2; say what was meant.
        let exponent = self
            .src
            .get(..fault.offset)
            .and_then(|b| b.chars().next_back());
        let at_e = self.src.get(fault.offset..).and_then(|a| a.chars().next());
        let message = match (exponent, at_e) {
            (Some(d), Some('e' | 'E')) if d.is_ascii_digit() || d == '.' => {
                "exponent notation (as 1e2) is not accepted: write the number in full (100)"
                    .to_string()
            }
            _ => fault.message,
        };
        NcError {
            line,
            column,
            message,
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Syntax: the gcode crate drives these visitors

/// One word of a block.
#[derive(Clone, Copy, Debug)]
enum Word {
    /// A G, M or T code.
    Code {
        letter: char,
        number: Number,
        offset: usize,
    },
    /// Any other letter with its value (in program units).
    Value {
        letter: char,
        value: f64,
        offset: usize,
    },
}

impl Word {
    fn offset(&self) -> usize {
        match *self {
            Word::Code { offset, .. } | Word::Value { offset, .. } => offset,
        }
    }
}

/// The words of one source block, in source order.
#[derive(Debug)]
struct RawBlock {
    start: usize,
    words: Vec<Word>,
}

/// Reads the syntax of `src`: blocks of words, and every syntax problem found.
fn scan(src: &str) -> (Vec<RawBlock>, Vec<Fault>) {
    let (text, code_faults) = prescan_codes(src);
    let mut scanner = Scanner {
        src: &text,
        blocks: Vec::new(),
        faults: Faults {
            src: &text,
            list: code_faults,
        },
    };
    gcode::core::parse(&text, &mut scanner);
    (scanner.blocks, scanner.faults.list)
}

/// Checks the numbers after G, M and T before the `gcode` crate sees them.
///
/// The crate drops a code whose number it cannot read without reporting it, and overflows
/// (panics in debug builds) on numbers from about 429 496 730 up. This scan follows the crate's
/// lexer (comments in nested parentheses or after `;`, whitespace, then an optional `.`, digits,
/// and an optional `.` with digits), reports every such number, and replaces the digits of an
/// overflowing one with zeros so that the crate can read the rest.
fn prescan_codes(src: &str) -> (Cow<'_, str>, Vec<Fault>) {
    let bytes = src.as_bytes();
    let mut faults = Vec::new();
    let mut zeroed: Vec<(usize, usize)> = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            b'(' => i = skip_paren_comment(bytes, i),
            b';' => {
                i = bytes[i..]
                    .iter()
                    .position(|&b| b == b'\n')
                    .map_or(bytes.len(), |p| i + p)
            }
            b'G' | b'g' | b'M' | b'm' | b'T' | b't' => {
                let (start, end) = code_number_token(bytes, i + 1);
                let token = src.get(start..end).unwrap_or("");
                if !token.is_empty() {
                    match code_number_check(token) {
                        CodeNumber::Valid => {}
                        CodeNumber::Invalid => faults
                            .push(Fault::new(i, invalid_code_message(bytes[i] as char, token))),
                        CodeNumber::Overflow => {
                            faults.push(Fault::new(
                                i,
                                unsupported_code_message(bytes[i] as char, token),
                            ));
                            zeroed.push((start, end));
                        }
                    }
                }
                i = end.max(i + 1);
            }
            _ => i += 1,
        }
    }
    if zeroed.is_empty() {
        return (Cow::Borrowed(src), faults);
    }
    let mut owned = bytes.to_vec();
    for (s, e) in zeroed {
        for b in &mut owned[s..e] {
            if b.is_ascii_digit() {
                *b = b'0';
            }
        }
    }
    // Only ASCII digits were replaced by ASCII digits: still valid UTF-8.
    let text = String::from_utf8(owned).map_or(Cow::Borrowed(src), Cow::Owned);
    (text, faults)
}

/// The index after a parenthesised comment starting at `i` (nested, may run to the end).
fn skip_paren_comment(bytes: &[u8], i: usize) -> usize {
    let mut depth = 0usize;
    for (k, &b) in bytes.iter().enumerate().skip(i) {
        match b {
            b'(' => depth += 1,
            b')' => {
                depth = depth.saturating_sub(1);
                if depth == 0 {
                    return k + 1;
                }
            }
            _ => {}
        }
    }
    bytes.len()
}

/// The byte range of the number token the lexer reads after a code letter ending at `i`.
fn code_number_token(bytes: &[u8], mut i: usize) -> (usize, usize) {
    while i < bytes.len() && matches!(bytes[i], b' ' | b'\t' | b'\r') {
        i += 1;
    }
    let start = i;
    if i >= bytes.len() || !(bytes[i].is_ascii_digit() || bytes[i] == b'.') {
        return (start, start);
    }
    if bytes[i] == b'.' {
        i += 1;
    }
    while i < bytes.len() && bytes[i].is_ascii_digit() {
        i += 1;
    }
    if i < bytes.len() && bytes[i] == b'.' {
        i += 1;
        while i < bytes.len() && bytes[i].is_ascii_digit() {
            i += 1;
        }
    }
    (start, i)
}

enum CodeNumber {
    Valid,
    Invalid,
    Overflow,
}

/// What `gcode::core::Number::from_str` would make of `token`.
fn code_number_check(token: &str) -> CodeNumber {
    let (major, minor) = match token.split_once('.') {
        None => (token, None),
        Some((a, b)) => (a, Some(b)),
    };
    let Ok(major) = major.parse::<u32>() else {
        return CodeNumber::Invalid;
    };
    let minor = match minor.map(str::parse::<u32>) {
        None => 0,
        Some(Ok(m)) if m < 10 => m,
        Some(_) => return CodeNumber::Invalid,
    };
    match major.checked_mul(10).and_then(|v| v.checked_add(minor)) {
        Some(_) => CodeNumber::Valid,
        None => CodeNumber::Overflow,
    }
}

fn supported_codes(letter: char) -> String {
    match letter.to_ascii_uppercase() {
        'G' => format!("the supported G codes are {SUPPORTED_G_CODES}"),
        'M' => format!("the supported M codes are {SUPPORTED_M_CODES}"),
        _ => "tool selection (T) is not supported: the machine carries one tool".to_string(),
    }
}

fn invalid_code_message(letter: char, token: &str) -> String {
    let l = letter.to_ascii_uppercase();
    format!(
        "`{l}{token}` is not a code number (a whole number with at most one decimal digit); {}",
        supported_codes(l)
    )
}

fn unsupported_code_message(letter: char, number: &str) -> String {
    let l = letter.to_ascii_uppercase();
    format!("{l}{number} is not supported: {}", supported_codes(l))
}

/// Collects the syntax problems the `gcode` crate reports.
struct Faults<'s> {
    src: &'s str,
    list: Vec<Fault>,
}

impl gcode::core::Diagnostics for Faults<'_> {
    fn emit_unknown_content(&mut self, text: &str, span: Span) {
        let shown: String = text.chars().take(20).collect();
        self.list.push(Fault::new(
            span.start,
            format!("`{shown}` is not G-code: {BLOCK_GRAMMAR}"),
        ));
    }

    fn emit_unexpected(&mut self, actual: &str, expected: &[TokenType], span: Span) {
        let fault = match self.code_letter_before(span.start) {
            Some((offset, letter)) if expected == [TokenType::Number] => Fault::new(
                offset,
                format!("`{letter}` must be followed by its code number, as {letter}1"),
            ),
            _ => Fault::new(span.start, unexpected_message(actual, expected)),
        };
        self.list.push(fault);
    }

    fn emit_parse_int_error(&mut self, value: &str, _error: std::num::ParseIntError, span: Span) {
        self.list.push(Fault::new(
            span.start,
            format!("`{value}` is not a line number: N takes a whole number below 4294967296"),
        ));
    }
}

impl Faults<'_> {
    /// The G, M or T letter right before `offset` (whitespace skipped), if any.
    fn code_letter_before(&self, offset: usize) -> Option<(usize, char)> {
        let before = self.src.get(..offset)?;
        let trimmed = before.trim_end_matches([' ', '\t', '\r']);
        let c = trimmed.chars().next_back()?;
        let letter = c.to_ascii_uppercase();
        matches!(letter, 'G' | 'M' | 'T').then(|| (trimmed.len() - c.len_utf8(), letter))
    }
}

fn unexpected_message(actual: &str, expected: &[TokenType]) -> String {
    let is_letter = actual.chars().count() == 1 && actual.chars().all(|c| c.is_ascii_alphabetic());
    let upper = actual.to_ascii_uppercase();
    match expected {
        [TokenType::Number] if is_letter => {
            format!("`{upper}` must be followed by a number, as {upper}10 or {upper}-2.5")
        }
        [TokenType::Number] => {
            format!("`{actual}` is not a number: numbers are written as 12, -3.5 or .25")
        }
        [TokenType::Letter] => format!(
            "the number `{actual}` belongs to no letter: every number follows its letter \
             (as X1.5); look for a doubled decimal point or a missing letter"
        ),
        [TokenType::Letter, TokenType::Comment] => format!(
            "`{actual}` is out of place: a sign goes between a letter and its number \
             (as X-1.5); block delete (/) is not supported"
        ),
        [TokenType::Letter, TokenType::Number] => {
            format!("`{upper}` must come first in its block, before any G or M code")
        }
        [TokenType::Eof] => format!("`{upper}` at the end of the program needs a number"),
        _ => {
            let names: Vec<&str> = expected.iter().map(|t| t.as_str()).collect();
            format!("unexpected `{actual}`: expected {}", names.join(" or "))
        }
    }
}

/// The value of a word, read again from the source as f64 (the crate reads f32).
fn word_value(src: &str, letter: char, value: Value<'_>, span: Span) -> Result<f64, String> {
    let literal = match value {
        Value::Literal(v) => f64::from(v),
        Value::Variable(name) => {
            return Err(format!(
                "parameters (#{name}) are not supported: write the number"
            ));
        }
    };
    let text = src.get(span.start..span.end()).unwrap_or("");
    let digits: String = text
        .chars()
        .skip(1)
        .filter(|c| !c.is_whitespace())
        .collect();
    let v = digits.parse::<f64>().unwrap_or(literal);
    if v.is_finite() {
        Ok(v)
    } else {
        let shown: String = digits.chars().take(24).collect();
        Err(format!(
            "{}{shown}…: the number is too large to be a finite value",
            letter.to_ascii_uppercase()
        ))
    }
}

struct Scanner<'s> {
    src: &'s str,
    blocks: Vec<RawBlock>,
    faults: Faults<'s>,
}

impl HasDiagnostics for Scanner<'_> {
    fn diagnostics(&mut self) -> &mut dyn gcode::core::Diagnostics {
        &mut self.faults
    }
}

impl<'s> ProgramVisitor for Scanner<'s> {
    fn start_block(&mut self) -> ControlFlow<impl BlockVisitor + '_> {
        ControlFlow::Continue(BlockScanner {
            src: self.src,
            words: Vec::new(),
            blocks: &mut self.blocks,
            faults: &mut self.faults,
        })
    }
}

struct BlockScanner<'a, 's> {
    src: &'s str,
    words: Vec<Word>,
    blocks: &'a mut Vec<RawBlock>,
    faults: &'a mut Faults<'s>,
}

impl HasDiagnostics for BlockScanner<'_, '_> {
    fn diagnostics(&mut self) -> &mut dyn gcode::core::Diagnostics {
        &mut *self.faults
    }
}

impl<'s> BlockScanner<'_, 's> {
    fn code(&mut self, letter: char, number: Number) -> CodeScanner<'_, 's> {
        CodeScanner {
            src: self.src,
            letter,
            number,
            words: &mut self.words,
            faults: &mut *self.faults,
        }
    }
}

impl BlockVisitor for BlockScanner<'_, '_> {
    fn comment(&mut self, value: &str, span: Span) {
        if value.starts_with('(') && (!value.ends_with(')') || value.contains('\n')) {
            self.faults.list.push(Fault::new(
                span.start,
                "comment not closed: a ( comment must end with ) on the same line",
            ));
        }
    }

    fn word_address(&mut self, letter: char, value: Value<'_>, span: Span) {
        push_value(self.src, &mut self.words, self.faults, letter, value, span);
    }

    fn start_general_code(&mut self, number: Number) -> ControlFlow<impl CommandVisitor + '_> {
        ControlFlow::Continue(self.code('G', number))
    }

    fn start_miscellaneous_code(
        &mut self,
        number: Number,
    ) -> ControlFlow<impl CommandVisitor + '_> {
        ControlFlow::Continue(self.code('M', number))
    }

    fn start_tool_change_code(&mut self, number: Number) -> ControlFlow<impl CommandVisitor + '_> {
        ControlFlow::Continue(self.code('T', number))
    }

    fn end_line(self, span: Span) {
        let mut words = self.words;
        words.sort_by_key(Word::offset);
        self.blocks.push(RawBlock {
            start: span.start,
            words,
        });
    }
}

fn push_value(
    src: &str,
    words: &mut Vec<Word>,
    faults: &mut Faults<'_>,
    letter: char,
    value: Value<'_>,
    span: Span,
) {
    match word_value(src, letter, value, span) {
        Ok(value) => words.push(Word::Value {
            letter: letter.to_ascii_uppercase(),
            value,
            offset: span.start,
        }),
        Err(message) => faults.list.push(Fault::new(span.start, message)),
    }
}

struct CodeScanner<'a, 's> {
    src: &'s str,
    letter: char,
    number: Number,
    words: &'a mut Vec<Word>,
    faults: &'a mut Faults<'s>,
}

impl HasDiagnostics for CodeScanner<'_, '_> {
    fn diagnostics(&mut self) -> &mut dyn gcode::core::Diagnostics {
        &mut *self.faults
    }
}

impl CommandVisitor for CodeScanner<'_, '_> {
    fn argument(&mut self, letter: char, value: Value<'_>, span: Span) {
        push_value(self.src, self.words, self.faults, letter, value, span);
    }

    fn end_command(self, span: Span) {
        self.words.push(Word::Code {
            letter: self.letter,
            number: self.number,
            offset: span.start,
        });
    }
}

// ---------------------------------------------------------------------------------------------
// Meaning: the words of a block, sorted

/// The words of one block, by kind.
struct Words {
    start: usize,
    g: Vec<(u32, usize)>,
    m: Vec<(u32, usize)>,
    values: [Option<(f64, usize)>; 26],
}

/// A code number ×10 (G91.1 is 911).
fn code_value(n: Number) -> u32 {
    n.major()
        .saturating_mul(10)
        .saturating_add(n.minor().map_or(0, |m| m.get()))
}

fn code_name(letter: char, code: u32) -> String {
    match code % 10 {
        0 => format!("{letter}{}", code / 10),
        m => format!("{letter}{}.{m}", code / 10),
    }
}

impl Words {
    fn sort(raw: &RawBlock) -> Result<Self, Fault> {
        let mut w = Words {
            start: raw.start,
            g: Vec::new(),
            m: Vec::new(),
            values: [None; 26],
        };
        for word in &raw.words {
            match *word {
                Word::Code {
                    letter,
                    number,
                    offset,
                } => match letter {
                    'G' => w.g.push((code_value(number), offset)),
                    'M' => w.m.push((code_value(number), offset)),
                    _ => return Err(Fault::new(offset, supported_codes('T'))),
                },
                Word::Value {
                    letter,
                    value,
                    offset,
                } => w.set(letter, value, offset)?,
            }
        }
        Ok(w)
    }

    fn set(&mut self, letter: char, value: f64, offset: usize) -> Result<(), Fault> {
        if !"XYZIJKRFSP".contains(letter) {
            return Err(Fault::new(
                offset,
                format!(
                    "the word {letter} is not supported: the accepted letters are {WORD_LETTERS}"
                ),
            ));
        }
        let slot = &mut self.values[(letter as u8 - b'A') as usize];
        if slot.is_some() {
            return Err(Fault::new(
                offset,
                format!("{letter} appears twice in the block: give it once"),
            ));
        }
        *slot = Some((value, offset));
        Ok(())
    }

    fn get(&self, letter: char) -> Option<(f64, usize)> {
        self.values
            .get((letter as u8).wrapping_sub(b'A') as usize)
            .copied()
            .flatten()
    }

    fn has_any(&self, letters: &str) -> bool {
        letters.chars().any(|l| self.get(l).is_some())
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum MotionMode {
    Rapid,
    Linear,
    Arc(ArcDirection),
}

impl MotionMode {
    fn name(self) -> &'static str {
        match self {
            MotionMode::Rapid => "G0",
            MotionMode::Linear => "G1",
            MotionMode::Arc(ArcDirection::Cw) => "G2",
            MotionMode::Arc(ArcDirection::Ccw) => "G3",
        }
    }
}

/// The G codes of one block, by modal group.
#[derive(Default)]
struct GCodes {
    motion: Option<(MotionMode, usize)>,
    dwell: Option<usize>,
    plane: Option<Plane>,
    unit_m: Option<f64>,
    incremental: Option<bool>,
}

fn set_once<T>(slot: &mut Option<T>, value: T, offset: usize, group: &str) -> Result<(), Fault> {
    if slot.is_some() {
        return Err(Fault::new(
            offset,
            format!("two {group} codes in one block: give one"),
        ));
    }
    *slot = Some(value);
    Ok(())
}

impl GCodes {
    fn sort(words: &Words) -> Result<Self, Fault> {
        let mut g = GCodes::default();
        for &(code, at) in &words.g {
            match code {
                0 => set_once(&mut g.motion, (MotionMode::Rapid, at), at, "motion")?,
                10 => set_once(&mut g.motion, (MotionMode::Linear, at), at, "motion")?,
                20 => set_once(
                    &mut g.motion,
                    (MotionMode::Arc(ArcDirection::Cw), at),
                    at,
                    "motion",
                )?,
                30 => set_once(
                    &mut g.motion,
                    (MotionMode::Arc(ArcDirection::Ccw), at),
                    at,
                    "motion",
                )?,
                40 => set_once(&mut g.dwell, at, at, "dwell (G4)")?,
                170 => set_once(&mut g.plane, Plane::Xy, at, "plane (G17, G18, G19)")?,
                180 => set_once(&mut g.plane, Plane::Zx, at, "plane (G17, G18, G19)")?,
                190 => set_once(&mut g.plane, Plane::Yz, at, "plane (G17, G18, G19)")?,
                200 => set_once(&mut g.unit_m, MM_PER_INCH * 1e-3, at, "unit (G20, G21)")?,
                210 => set_once(&mut g.unit_m, 1e-3, at, "unit (G20, G21)")?,
                900 => set_once(&mut g.incremental, false, at, "distance (G90, G91)")?,
                910 => set_once(&mut g.incremental, true, at, "distance (G90, G91)")?,
                940 => {}
                other => {
                    return Err(Fault::new(
                        at,
                        format!(
                            "{} is not supported: {}",
                            code_name('G', other),
                            supported_codes('G')
                        ),
                    ));
                }
            }
        }
        if let (Some(at), Some((mode, _))) = (g.dwell, g.motion) {
            return Err(Fault::new(
                at,
                format!("G4 (dwell) and {} cannot share a block", mode.name()),
            ));
        }
        Ok(g)
    }
}

/// The M codes of one block.
#[derive(Default)]
struct MCodes {
    spindle: Option<(u32, usize)>,
    end: bool,
}

impl MCodes {
    fn sort(words: &Words) -> Result<Self, Fault> {
        let mut m = MCodes::default();
        let mut end = None;
        for &(code, at) in &words.m {
            match code {
                30 | 40 | 50 => set_once(&mut m.spindle, (code, at), at, "spindle (M3, M4, M5)")?,
                20 | 300 => set_once(&mut end, (), at, "program end (M2, M30)")?,
                other => {
                    return Err(Fault::new(
                        at,
                        format!(
                            "{} is not supported: {}",
                            code_name('M', other),
                            supported_codes('M')
                        ),
                    ));
                }
            }
        }
        m.end = end.is_some();
        Ok(m)
    }
}

// ---------------------------------------------------------------------------------------------
// Meaning: the modal machine

enum Flow {
    Continue,
    End,
}

/// The modal state and the blocks made so far.
struct Interpreter<'l, 's> {
    locator: &'l Locator<'s>,
    start: Vector3<f64>,
    position: Vector3<f64>,
    motion: Option<MotionMode>,
    plane: Plane,
    incremental: bool,
    unit_m: f64,
    feed_m_s: Option<f64>,
    spindle_rpm: f64,
    spindle: Spindle,
    blocks: Vec<Block>,
}

impl<'l, 's> Interpreter<'l, 's> {
    fn new(start: Vector3<f64>, locator: &'l Locator<'s>) -> Self {
        Interpreter {
            locator,
            start,
            position: start,
            motion: None,
            plane: Plane::Xy,
            incremental: false,
            unit_m: 1e-3,
            feed_m_s: None,
            spindle_rpm: 0.0,
            spindle: Spindle::Stopped,
            blocks: Vec::new(),
        }
    }

    fn finish(self) -> Program {
        Program {
            start: self.start,
            blocks: self.blocks,
        }
    }

    fn block(&mut self, raw: &RawBlock) -> Result<Flow, Fault> {
        let words = Words::sort(raw)?;
        let g = GCodes::sort(&words)?;
        let m = MCodes::sort(&words)?;
        self.modes(&g);
        self.feed(&words)?;
        self.spindle(&words, &m)?;
        if let Some(motion) = self.motion_of(&words, &g)? {
            self.blocks.push(Block {
                motion,
                spindle: self.spindle,
                span: self.locator.span(words.start),
            });
        }
        Ok(if m.end { Flow::End } else { Flow::Continue })
    }

    fn modes(&mut self, g: &GCodes) {
        if let Some(u) = g.unit_m {
            self.unit_m = u;
        }
        if let Some(p) = g.plane {
            self.plane = p;
        }
        if let Some(i) = g.incremental {
            self.incremental = i;
        }
    }

    fn unit_name(&self) -> &'static str {
        if self.unit_m > 2e-3 { "in" } else { "mm" }
    }

    fn feed(&mut self, w: &Words) -> Result<(), Fault> {
        let Some((f, at)) = w.get('F') else {
            return Ok(());
        };
        let v = f * self.unit_m / 60.0;
        if !(f > 0.0 && v.is_finite() && v > 0.0) {
            return Err(Fault::new(
                at,
                format!("F{f}: the feed must be > 0 ({}/min)", self.unit_name()),
            ));
        }
        self.feed_m_s = Some(v);
        Ok(())
    }

    fn spindle(&mut self, w: &Words, m: &MCodes) -> Result<(), Fault> {
        if let Some((s, at)) = w.get('S') {
            if !(0.0..=MAX_SPINDLE_RPM).contains(&s) {
                return Err(Fault::new(
                    at,
                    format!("S{s}: the spindle speed must be from 0 to {MAX_SPINDLE_RPM} rpm"),
                ));
            }
            self.spindle_rpm = s;
        }
        self.spindle = match (m.spindle.map(|(c, _)| c), self.spindle) {
            (Some(30), _) | (None, Spindle::Clockwise(_)) => Spindle::Clockwise(self.spindle_rpm),
            (Some(40), _) | (None, Spindle::CounterClockwise(_)) => {
                Spindle::CounterClockwise(self.spindle_rpm)
            }
            _ => Spindle::Stopped,
        };
        Ok(())
    }

    fn motion_of(&mut self, w: &Words, g: &GCodes) -> Result<Option<Motion>, Fault> {
        if let Some(at) = g.dwell {
            return self.dwell(w, at).map(Some);
        }
        if let Some((_, at)) = w.get('P') {
            return Err(Fault::new(
                at,
                "P is only used with G4 (dwell time in seconds)",
            ));
        }
        if let Some((mode, _)) = g.motion {
            self.motion = Some(mode);
        }
        let has_axis = w.has_any("XYZ");
        if !has_axis && !w.has_any("IJKR") {
            return Ok(None);
        }
        let Some(mode) = self.motion else {
            return Err(Fault::new(
                w.start,
                "axis words without a motion mode: give G0, G1, G2 or G3 first",
            ));
        };
        let at = g.motion.map_or(w.start, |(_, at)| at);
        let to = self.target(w)?;
        let motion = match mode {
            MotionMode::Rapid | MotionMode::Linear => self.straight(w, mode, at, to)?,
            MotionMode::Arc(direction) => self.arc(w, direction, at, to)?,
        };
        self.position = match &motion {
            Motion::Rapid { to } | Motion::Linear { to, .. } | Motion::Arc { to, .. } => *to,
            Motion::Dwell { .. } => self.position,
        };
        Ok(Some(motion))
    }

    fn dwell(&self, w: &Words, at: usize) -> Result<Motion, Fault> {
        if let Some((_, off)) = ['X', 'Y', 'Z', 'I', 'J', 'K', 'R']
            .into_iter()
            .find_map(|l| w.get(l))
        {
            return Err(Fault::new(
                off,
                "G4 takes only P, the dwell time in seconds (as G4 P1.5); no axis or arc words",
            ));
        }
        let Some((p, p_at)) = w.get('P') else {
            return Err(Fault::new(
                at,
                "G4 needs P, the dwell time in seconds (as G4 P1.5)",
            ));
        };
        if p < 0.0 {
            return Err(Fault::new(p_at, format!("P{p}: a dwell must be >= 0 s")));
        }
        Ok(Motion::Dwell { seconds: p })
    }

    /// The end point of a motion block, m.
    fn target(&self, w: &Words) -> Result<Vector3<f64>, Fault> {
        let mut to = self.position;
        for (k, letter) in ['X', 'Y', 'Z'].into_iter().enumerate() {
            if let Some((v, at)) = w.get(letter) {
                let d = v * self.unit_m;
                to[k] = if self.incremental { to[k] + d } else { d };
                if !to[k].is_finite() {
                    return Err(Fault::new(
                        at,
                        format!("{letter}{v}: the position is too large to be finite"),
                    ));
                }
            }
        }
        Ok(to)
    }

    fn feed_for(&self, mode: MotionMode, at: usize) -> Result<f64, Fault> {
        self.feed_m_s.ok_or_else(|| {
            Fault::new(
                at,
                format!(
                    "{} needs a feed: no F has been given (F in {}/min, > 0)",
                    mode.name(),
                    self.unit_name()
                ),
            )
        })
    }

    fn straight(
        &self,
        w: &Words,
        mode: MotionMode,
        at: usize,
        to: Vector3<f64>,
    ) -> Result<Motion, Fault> {
        if let Some(off) = ['I', 'J', 'K', 'R']
            .iter()
            .find_map(|&l| w.get(l).map(|v| v.1))
        {
            return Err(Fault::new(
                off,
                format!(
                    "I, J, K and R are only used with G2 and G3, not with {}",
                    mode.name()
                ),
            ));
        }
        Ok(match mode {
            MotionMode::Rapid => Motion::Rapid { to },
            _ => Motion::Linear {
                to,
                feed: self.feed_for(mode, at)?,
            },
        })
    }

    fn arc(
        &self,
        w: &Words,
        direction: ArcDirection,
        at: usize,
        to: Vector3<f64>,
    ) -> Result<Motion, Fault> {
        let mode = MotionMode::Arc(direction);
        let feed = self.feed_for(mode, at)?;
        let geometry = ArcInput {
            plane: self.plane,
            direction,
            start: self.position,
            to,
            unit_m: self.unit_m,
            at,
        };
        let (center, to) = geometry.resolve(w)?;
        Ok(Motion::Arc {
            to,
            center,
            plane: self.plane,
            direction,
            feed,
        })
    }
}

// ---------------------------------------------------------------------------------------------
// Arcs

/// The indices of the plane's first and second axis and of its normal (u × v = n).
fn plane_indices(plane: Plane) -> [usize; 3] {
    match plane {
        Plane::Xy => [0, 1, 2],
        Plane::Zx => [2, 0, 1],
        Plane::Yz => [1, 2, 0],
    }
}

fn plane_code(plane: Plane) -> &'static str {
    match plane {
        Plane::Xy => "G17 (XY)",
        Plane::Zx => "G18 (ZX)",
        Plane::Yz => "G19 (YZ)",
    }
}

const OFFSET_LETTERS: [char; 3] = ['I', 'J', 'K'];

struct ArcInput {
    plane: Plane,
    direction: ArcDirection,
    start: Vector3<f64>,
    to: Vector3<f64>,
    unit_m: f64,
    at: usize,
}

impl ArcInput {
    fn in_plane(&self, p: &Vector3<f64>) -> (f64, f64) {
        let [u, v, _] = plane_indices(self.plane);
        (p[u], p[v])
    }

    fn offset_names(&self) -> String {
        let [u, v, _] = plane_indices(self.plane);
        format!(
            "{} and {}",
            OFFSET_LETTERS[u.min(v)],
            OFFSET_LETTERS[u.max(v)]
        )
    }

    /// Centre and end point (snapped to the start for a full circle).
    fn resolve(&self, w: &Words) -> Result<(Vector3<f64>, Vector3<f64>), Fault> {
        let [u, v, _] = plane_indices(self.plane);
        let (su, sv) = self.in_plane(&self.start);
        let (eu, ev) = self.in_plane(&self.to);
        let full = (eu - su).hypot(ev - sv) < FULL_CIRCLE_TOLERANCE_M;
        let mut to = self.to;
        if full {
            to[u] = self.start[u];
            to[v] = self.start[v];
        }
        let has_offset = w.has_any("IJK");
        let center = match (w.get('R'), has_offset) {
            (Some((_, at)), true) => {
                return Err(Fault::new(
                    at,
                    "give the arc's centre with I/J/K or its radius with R, not both",
                ));
            }
            (Some((r, at)), false) => self.center_from_radius(r, at, full)?,
            (None, true) => self.center_from_offsets(w, &to)?,
            (None, false) => {
                return Err(Fault::new(
                    self.at,
                    format!(
                        "{} needs the arc's centre ({} in {}) or its radius R",
                        MotionMode::Arc(self.direction).name(),
                        self.offset_names(),
                        plane_code(self.plane)
                    ),
                ));
            }
        };
        Ok((center, to))
    }

    fn center_from_offsets(&self, w: &Words, to: &Vector3<f64>) -> Result<Vector3<f64>, Fault> {
        let [u, v, n] = plane_indices(self.plane);
        if let Some((_, at)) = w.get(OFFSET_LETTERS[n]) {
            return Err(Fault::new(
                at,
                format!(
                    "{} is along the arc's axis in {}: the centre is given by {}",
                    OFFSET_LETTERS[n],
                    plane_code(self.plane),
                    self.offset_names()
                ),
            ));
        }
        let mut center = self.start;
        for k in [u, v] {
            if let Some((d, _)) = w.get(OFFSET_LETTERS[k]) {
                center[k] += d * self.unit_m;
            }
        }
        if !center.iter().all(|c| c.is_finite()) {
            return Err(Fault::new(
                self.at,
                "the arc's centre is too far to be finite",
            ));
        }
        let radius = |p: &Vector3<f64>| (p[u] - center[u]).hypot(p[v] - center[v]);
        let (r0, r1) = (radius(&self.start), radius(to));
        if r0 < FULL_CIRCLE_TOLERANCE_M {
            return Err(Fault::new(
                self.at,
                format!(
                    "the arc's centre ({}) is at its start point: the radius is 0",
                    self.offset_names()
                ),
            ));
        }
        if (r0 - r1).abs() > RADIUS_TOLERANCE_M {
            return Err(Fault::new(
                self.at,
                format!(
                    "the end point is not on the arc's circle: the start is {:.4} mm from the \
                     centre and the end {:.4} mm (they may differ by at most 0.001 mm)",
                    r0 * 1e3,
                    r1 * 1e3
                ),
            ));
        }
        Ok(center)
    }

    fn center_from_radius(&self, r: f64, at: usize, full: bool) -> Result<Vector3<f64>, Fault> {
        let radius = r * self.unit_m;
        if radius == 0.0 || !radius.is_finite() {
            return Err(Fault::new(at, format!("R{r}: the radius must not be 0")));
        }
        if full {
            return Err(Fault::new(
                at,
                format!(
                    "a full circle (end point = start point) cannot be given with R: give its \
                     centre with {}",
                    self.offset_names()
                ),
            ));
        }
        let [u, v, _] = plane_indices(self.plane);
        let (su, sv) = self.in_plane(&self.start);
        let (eu, ev) = self.in_plane(&self.to);
        let (cu, cv) = (eu - su, ev - sv);
        let chord = cu.hypot(cv);
        if chord > 2.0 * radius.abs() + RADIUS_TOLERANCE_M {
            return Err(Fault::new(
                at,
                format!(
                    "R{r}: the chord from the start to the end point is {:.4} mm, longer than \
                     the diameter 2|R| = {:.4} mm",
                    chord * 1e3,
                    2.0 * radius.abs() * 1e3
                ),
            ));
        }
        let h = (radius * radius - chord * chord / 4.0).max(0.0).sqrt();
        // Left of the chord (seen from +normal) for a short CCW arc; R < 0 or CW flips it.
        let ccw = self.direction == ArcDirection::Ccw;
        let side = if ccw != (radius < 0.0) { 1.0 } else { -1.0 };
        let mut center = self.start;
        center[u] = su + cu / 2.0 - side * h * cv / chord;
        center[v] = sv + cv / 2.0 + side * h * cu / chord;
        Ok(center)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn ok(text: &str) -> Program {
        parse(text, Vector3::zeros()).unwrap_or_else(|e| panic!("{text:?}: {e}"))
    }

    fn err(text: &str) -> NcError {
        match parse(text, Vector3::zeros()) {
            Ok(p) => panic!("{text:?} was accepted: {p:?}"),
            Err(e) => e,
        }
    }

    fn close(a: Vector3<f64>, b: [f64; 3]) -> bool {
        (a - Vector3::from(b)).norm() < 1e-12
    }

    #[test]
    fn lines_and_rapids_in_si_units() {
        let p = ok("G21 G90\nG0 X10 Y20 Z5\nG1 X15 F600\n");
        assert_eq!(p.blocks.len(), 2);
        assert_eq!(
            p.blocks[0].motion,
            Motion::Rapid {
                to: Vector3::new(0.010, 0.020, 0.005)
            }
        );
        match p.blocks[1].motion {
            Motion::Linear { to, feed } => {
                assert!(close(to, [0.015, 0.020, 0.005]));
                assert!(
                    (feed - 0.01).abs() < 1e-15,
                    "600 mm/min = 0.01 m/s, got {feed}"
                );
            }
            ref m => panic!("{m:?}"),
        }
        assert_eq!(p.blocks[1].span, SourceSpan { line: 3, column: 1 });
    }

    #[test]
    fn numbers_keep_f64_precision() {
        // f32 would round 123.456789 mm by ~4 nm; the parser reads the text as f64.
        let p = ok("G0 X123.456789");
        let Motion::Rapid { to } = p.blocks[0].motion else {
            panic!()
        };
        assert_eq!(to.x, 123.456789 * 1e-3);
    }

    #[test]
    fn incremental_and_inches() {
        let p = ok("G91 G20\nG0 X1 Y-2\nX1\nG90 G21 G0 Z3");
        let ends: Vec<Vector3<f64>> = p
            .blocks
            .iter()
            .map(|b| match b.motion {
                Motion::Rapid { to } => to,
                _ => panic!(),
            })
            .collect();
        assert!(close(ends[0], [0.0254, -0.0508, 0.0]));
        assert!(close(ends[1], [0.0508, -0.0508, 0.0]));
        assert!(close(ends[2], [0.0508, -0.0508, 0.003]));
    }

    #[test]
    fn feed_is_modal_and_in_units_per_minute() {
        let p = ok("G20 G1 X1 F10\nG21 X2\n");
        for b in &p.blocks {
            let Motion::Linear { feed, .. } = b.motion else {
                panic!()
            };
            // 10 in/min = 254 mm/min = 4.2333 mm/s, kept after G21.
            assert!((feed - 0.254 / 60.0).abs() < 1e-15);
        }
    }

    #[test]
    fn comments_line_numbers_blank_lines_and_case() {
        let p = ok(
            "%\nO1000\n(header)\n\n; a comment\nN10 g1 x1 f100 (inline) ; trailing\n\nN20 X2\n%\n",
        );
        assert_eq!(p.blocks.len(), 2);
        assert_eq!(p.blocks[0].span, SourceSpan { line: 6, column: 1 });
        assert_eq!(p.blocks[1].span.line, 8);
    }

    #[test]
    fn full_circle_with_ijk() {
        let p = ok("G0 X10 Y0\nG3 X10 Y0 I-10 J0 F100");
        let Motion::Arc {
            to,
            center,
            direction,
            plane,
            ..
        } = p.blocks[1].motion
        else {
            panic!()
        };
        assert!(close(center, [0.0, 0.0, 0.0]));
        assert_eq!(to, Vector3::new(0.010, 0.0, 0.0));
        assert_eq!((direction, plane), (ArcDirection::Ccw, Plane::Xy));
        // Omitting the end point is the same full circle.
        let q = ok("G0 X10\nG2 I-10 F100");
        let Motion::Arc {
            to,
            center,
            direction,
            ..
        } = q.blocks[1].motion
        else {
            panic!()
        };
        assert!(close(center, [0.0, 0.0, 0.0]));
        assert_eq!(to, Vector3::new(0.010, 0.0, 0.0));
        assert_eq!(direction, ArcDirection::Cw);
    }

    #[test]
    fn arcs_in_zx_and_yz_planes() {
        // G18: I and K; centre 10 mm along -X of the start.
        let p = ok("G18 G0 X10 Z0\nG2 X-10 Z0 I-10 K0 F100");
        let Motion::Arc { center, plane, .. } = p.blocks[1].motion else {
            panic!()
        };
        assert_eq!(plane, Plane::Zx);
        assert!(close(center, [0.0, 0.0, 0.0]));
        let q = ok("G19 G0 Y5 Z0\nG3 Y0 Z5 J-5 F100");
        let Motion::Arc { center, plane, .. } = q.blocks[1].motion else {
            panic!()
        };
        assert_eq!(plane, Plane::Yz);
        assert!(close(center, [0.0, 0.0, 0.0]));
    }

    #[test]
    fn helix_keeps_the_centre_in_the_start_plane() {
        let p = ok("G0 X10 Z0\nG3 X10 Y0 Z2 I-10 F100");
        let Motion::Arc { to, center, .. } = p.blocks[1].motion else {
            panic!()
        };
        assert!(close(center, [0.0, 0.0, 0.0]));
        assert!(close(to, [0.010, 0.0, 0.002]));
    }

    #[test]
    fn r_arcs_pick_the_short_or_long_side() {
        // From (10, 0) to (0, 10) with |R| = 10: centres (0, 0) and (10, 10).
        let centre = |text: &str| {
            let p = ok(text);
            match p.blocks[1].motion {
                Motion::Arc { center, .. } => center,
                _ => panic!(),
            }
        };
        assert!(close(centre("G0 X10\nG3 X0 Y10 R10 F100"), [0.0, 0.0, 0.0]));
        assert!(close(
            centre("G0 X10\nG3 X0 Y10 R-10 F100"),
            [0.010, 0.010, 0.0]
        ));
        assert!(close(
            centre("G0 X10\nG2 X0 Y10 R10 F100"),
            [0.010, 0.010, 0.0]
        ));
        assert!(close(
            centre("G0 X10\nG2 X0 Y10 R-10 F100"),
            [0.0, 0.0, 0.0]
        ));
        // A half circle: chord = 2R.
        assert!(close(centre("G0 X10\nG2 X-10 R10 F100"), [0.0, 0.0, 0.0]));
    }

    #[test]
    fn dwell_spindle_and_end() {
        let p = ok("S1200 M3\nG4 P1.5\nM4\nG0 X1\nM5 G0 X2\nM30\nG0 X99\nthis is not read");
        assert_eq!(p.blocks.len(), 3);
        assert_eq!(p.blocks[0].motion, Motion::Dwell { seconds: 1.5 });
        assert_eq!(p.blocks[0].spindle, Spindle::Clockwise(1200.0));
        assert_eq!(p.blocks[1].spindle, Spindle::CounterClockwise(1200.0));
        assert_eq!(p.blocks[2].spindle, Spindle::Stopped);
        let Motion::Rapid { to } = p.blocks[2].motion else {
            panic!()
        };
        assert_eq!(to.x, 0.002);
    }

    #[test]
    fn error_display_names_line_and_column() {
        let e = err("G0 X1\nG1 X2");
        assert_eq!((e.line, e.column), (2, 1));
        assert!(
            e.to_string()
                .starts_with("line 2, column 1: G1 needs a feed"),
            "{e}"
        );
    }

    #[test]
    fn syntax_errors() {
        let e = err("G0 X0\nG1 X1..2 F100");
        assert_eq!((e.line, e.column), (2, 7), "{e}");
        assert!(e.message.contains("`.2`"), "{e}");
        let e = err("G1 X Y2 F100");
        assert_eq!((e.line, e.column), (1, 4), "{e}");
        assert!(
            e.message.contains("`X` must be followed by a number"),
            "{e}"
        );
        let e = err("G X1");
        assert_eq!((e.line, e.column), (1, 1), "{e}");
        assert!(
            e.message
                .contains("`G` must be followed by its code number"),
            "{e}"
        );
        let e = err("G0 X1 $");
        assert_eq!(e.column, 7, "{e}");
        let e = err("G0 X1 (not closed\nG0 X2");
        assert!(e.message.contains("comment not closed"), "{e}");
        let e = err("G1. X1");
        assert!(e.message.contains("`G1.` is not a code number"), "{e}");
    }

    #[test]
    fn exponents_spindle_bounds_and_a_byte_order_mark() {
        let e = err("G1 X1e2 F100");
        assert_eq!((e.line, e.column), (1, 6), "{e}");
        assert!(e.message.contains("exponent notation"), "{e}");
        // An E that follows a space is a word of its own, named as such.
        let e = err("G1 X1 E2 F100");
        assert!(e.message.contains("the word E is not supported"), "{e}");
        let e = err("M3 S200001");
        assert!(e.message.contains("from 0 to 200000 rpm"), "{e}");
        assert!(err("M3 S-1").message.contains("from 0 to 200000 rpm"));
        let p = parse("\u{feff}M3 S200000\nG1 X1 F100", Vector3::zeros()).expect("BOM skipped");
        assert_eq!(p.blocks[0].spindle, Spindle::Clockwise(200_000.0));
        let e = err("\u{feff}G1 A1");
        assert_eq!(
            (e.line, e.column),
            (1, 4),
            "columns as an editor shows them: {e}"
        );
    }

    #[test]
    fn unsupported_codes_and_words() {
        let e = err("G0 X1\nG41 X2");
        assert_eq!((e.line, e.column), (2, 1));
        assert!(e.message.contains("G41 is not supported"), "{e}");
        assert!(e.message.contains(SUPPORTED_G_CODES), "{e}");
        let e = err("M8");
        assert!(
            e.message.contains("M8 is not supported") && e.message.contains(SUPPORTED_M_CODES),
            "{e}"
        );
        let e = err("G0 A10");
        assert!(e.message.contains("the word A is not supported"), "{e}");
        let e = err("T1 M6");
        assert!(e.message.contains("tool selection"), "{e}");
        // The gcode crate overflows (panics) on this one and silently drops `G1.23`.
        let e = err("G999999999 X1");
        assert!(e.message.contains("G999999999 is not supported"), "{e}");
        let e = err("G0 X0\nG1.23 X4");
        assert_eq!((e.line, e.column), (2, 1));
        assert!(e.message.contains("`G1.23` is not a code number"), "{e}");
        let e = err("G4294967295 X1");
        assert!(e.message.contains("G4294967295 is not supported"), "{e}");
        let e = err("G0 G1 X1 F100");
        assert!(e.message.contains("two motion codes"), "{e}");
        let e = err("G0 X1 X2");
        assert!(e.message.contains("X appears twice"), "{e}");
    }

    #[test]
    fn feed_errors() {
        let e = err("G2 X0 Y0 I1");
        assert!(e.message.contains("G2 needs a feed"), "{e}");
        let e = err("G1 X1 F0");
        assert_eq!(e.column, 7);
        assert!(
            e.message.contains("F0: the feed must be > 0 (mm/min)"),
            "{e}"
        );
        let e = err("G1 X1 F-5");
        assert!(e.message.contains("must be > 0"), "{e}");
    }

    #[test]
    fn arc_errors() {
        let e = err("G0 X10\nG3 X0 Y10.01 I-10 F100");
        assert_eq!(e.line, 2);
        assert!(
            e.message.contains("10.0000 mm") && e.message.contains("10.0100 mm"),
            "{e}"
        );
        // 0.0009 mm off is accepted.
        ok("G0 X10\nG3 X0 Y10.0009 I-10 F100");
        let e = err("G0 X10\nG3 X0 Y10 F100");
        assert!(
            e.message
                .contains("needs the arc's centre (I and J in G17 (XY)) or its radius R"),
            "{e}"
        );
        let e = err("G0 X10\nG3 X-20 Y0 R10 F100");
        assert!(
            e.message
                .contains("30.0000 mm, longer than the diameter 2|R| = 20.0000 mm"),
            "{e}"
        );
        let e = err("G0 X10\nG3 X10 R10 F100");
        assert!(e.message.contains("full circle"), "{e}");
        let e = err("G0 X10\nG3 X0 Y10 I-10 R10 F100");
        assert!(e.message.contains("not both"), "{e}");
        let e = err("G0 X10\nG3 I-10 K1 F100");
        assert!(e.message.contains("K is along the arc's axis"), "{e}");
        let e = err("G0 X10\nG3 I0 F100");
        assert!(e.message.contains("radius is 0"), "{e}");
        let e = err("G1 X1 I1 F100");
        assert!(e.message.contains("only used with G2 and G3"), "{e}");
    }

    #[test]
    fn dwell_errors() {
        let e = err("G4 P-1");
        assert_eq!(e.column, 4);
        assert!(e.message.contains("P-1: a dwell must be >= 0 s"), "{e}");
        let e = err("G4");
        assert!(e.message.contains("G4 needs P"), "{e}");
        let e = err("G4 X1.5");
        assert!(e.message.contains("G4 takes only P"), "{e}");
        let e = err("G1 X1 P2 F100");
        assert!(e.message.contains("P is only used with G4"), "{e}");
    }

    #[test]
    fn infinite_values_are_refused() {
        let big = format!("G0 X1{}", "0".repeat(400));
        let e = err(&big);
        assert!(e.message.contains("too large"), "{e}");
        let far = parse(
            &format!("G91 G0 X1{}", "0".repeat(305)),
            Vector3::new(f64::MAX, 0.0, 0.0),
        );
        assert!(far.is_err_and(|e| e.message.contains("too large")));
        assert!(parse("G0 X1", Vector3::new(f64::NAN, 0.0, 0.0)).is_err());
    }

    #[test]
    fn motion_words_need_a_mode() {
        let e = err("X10");
        assert!(e.message.contains("without a motion mode"), "{e}");
    }

    #[test]
    fn first_error_in_reading_order() {
        // A semantic error on line 1 is reported before a syntax error on line 2 ...
        let e = err("G1 X1\nG1 X1..2");
        assert_eq!(e.line, 1);
        // ... and a syntax error after M30 is not read at all.
        ok("M30\nG1 X1..2");
    }

    const VOCABULARY: &[&str] = &[
        "G",
        "M",
        "T",
        "N",
        "O",
        "X",
        "Y",
        "Z",
        "I",
        "J",
        "K",
        "R",
        "F",
        "S",
        "P",
        "A",
        "g",
        "x",
        "0",
        "1",
        "2",
        "3",
        "4",
        "17",
        "18",
        "19",
        "20",
        "21",
        "30",
        "90",
        "91",
        "-",
        "+",
        ".",
        "..",
        "1.5",
        "-0.5",
        "999999999",
        "4294967295",
        "429496730",
        "99999999999999999999",
        "1e5",
        " ",
        "\t",
        "\r",
        "\n",
        "(",
        ")",
        ";",
        "%",
        "/",
        "#1",
        "é",
        "G2 X0 Y0 I1 F100",
        "G3 R5",
        "G4 P",
        "M30",
        "F0",
        "(comment)",
    ];

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        #[test]
        fn never_panics_on_random_text(text in any::<String>()) {
            let _ = parse(&text, Vector3::zeros());
        }

        #[test]
        fn never_panics_on_token_soup(
            tokens in proptest::collection::vec(proptest::sample::select(VOCABULARY), 0..60)
        ) {
            let text = tokens.concat();
            match parse(&text, Vector3::zeros()) {
                Ok(p) => {
                    for b in &p.blocks {
                        let finite = match b.motion {
                            Motion::Rapid { to } => to.iter().all(|c| c.is_finite()),
                            Motion::Linear { to, feed } => to.iter().all(|c| c.is_finite()) && feed > 0.0,
                            Motion::Arc { to, center, feed, .. } => {
                                to.iter().chain(center.iter()).all(|c| c.is_finite()) && feed > 0.0
                            }
                            Motion::Dwell { seconds } => seconds >= 0.0,
                        };
                        prop_assert!(finite, "{text:?}: {b:?}");
                    }
                }
                Err(e) => {
                    prop_assert!(e.line >= 1 && e.column >= 1);
                    prop_assert!(e.line <= text.lines().count() + 1, "{text:?}: {e}");
                }
            }
        }
    }
}
