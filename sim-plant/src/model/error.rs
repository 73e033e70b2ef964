//! Errors from reading a model file: always with the file, and with line and column when the
//! problem has a place in the text.

use std::fmt;
use std::ops::Range;

/// What went wrong with a model file, and where.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The file could not be read or written.
    #[error("{file}: {source}")]
    Io {
        /// Path as given.
        file: String,
        /// Underlying error.
        source: std::io::Error,
    },
    /// Syntax, unknown key, wrong type, wrong unit, out-of-range value.
    #[error("{0}")]
    At(Located),
    /// A model-wide inconsistency that has no single place in the text.
    #[error("{file}: {message}")]
    Invalid {
        /// File name.
        file: String,
        /// What is inconsistent.
        message: String,
    },
}

/// A message pinned to `file:line:col` (1-based; column counts characters).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Located {
    /// File name.
    pub file: String,
    /// 1-based line.
    pub line: usize,
    /// 1-based column (characters).
    pub col: usize,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for Located {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}:{}:{}: {}",
            self.file, self.line, self.col, self.message
        )
    }
}

impl ModelError {
    /// An error at byte range `span` of `text` (start of the range), or file-wide if `None`.
    pub fn at(file: &str, text: &str, span: Option<Range<usize>>, message: String) -> Self {
        match span {
            Some(span) => {
                let (line, col) = line_col(text, span.start);
                ModelError::At(Located {
                    file: file.to_string(),
                    line,
                    col,
                    message,
                })
            }
            None => ModelError::Invalid {
                file: file.to_string(),
                message,
            },
        }
    }

    /// The location, if the error has one.
    pub fn location(&self) -> Option<&Located> {
        match self {
            ModelError::At(l) => Some(l),
            _ => None,
        }
    }
}

/// 1-based (line, column) of byte `offset` in `text`; the column counts characters, so a
/// `·` or `²` before the error does not shift it.
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map(|i| i + 1).unwrap_or(0);
    let col = text[line_start..offset].chars().count() + 1;
    (line, col)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_col_counts_lines_and_characters() {
        let t = "a = 1\nb·c = 2\n";
        assert_eq!(line_col(t, 0), (1, 1));
        assert_eq!(line_col(t, 6), (2, 1));
        let pos = t.find('c').unwrap();
        assert_eq!(line_col(t, pos), (2, 3));
        assert_eq!(line_col(t, 999), (3, 1));
    }
}
