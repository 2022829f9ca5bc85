//! How a foreign CSV is written: its field separator and its decimal mark, detected from the
//! file or given by the user; a UTF-8 byte-order mark, CRLF line ends, a missing final line end
//! and NUL padding are accepted as they come.

/// A CSV dialect: field separator and decimal mark.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dialect {
    /// The field separator (`,`, `;` or a tab).
    pub separator: u8,
    /// Whether numbers use a decimal comma (`0,365`), as spreadsheets in many locales write.
    pub decimal_comma: bool,
}

impl Default for Dialect {
    fn default() -> Self {
        Self::COMMA
    }
}

impl Dialect {
    /// `,` separators, decimal point.
    pub const COMMA: Dialect = Dialect {
        separator: b',',
        decimal_comma: false,
    };
    /// `;` separators, decimal point.
    pub const SEMICOLON: Dialect = Dialect {
        separator: b';',
        decimal_comma: false,
    };
    /// `;` separators, decimal comma (German, French… spreadsheet exports).
    pub const SEMICOLON_DECIMAL_COMMA: Dialect = Dialect {
        separator: b';',
        decimal_comma: true,
    };
    /// Tab separators, decimal point.
    pub const TAB: Dialect = Dialect {
        separator: b'\t',
        decimal_comma: false,
    };
    /// Tab separators, decimal comma.
    pub const TAB_DECIMAL_COMMA: Dialect = Dialect {
        separator: b'\t',
        decimal_comma: true,
    };

    /// The separator as a person reads it (`,`, `;`, `tab`).
    pub fn separator_name(&self) -> String {
        match self.separator {
            b'\t' => "tab".into(),
            c => (c as char).to_string(),
        }
    }

    /// "`;` separators, decimal comma".
    pub fn describe(&self) -> String {
        format!(
            "`{}` separators, decimal {}",
            self.separator_name(),
            if self.decimal_comma { "comma" } else { "point" }
        )
    }

    /// The number in a cell (surrounding blanks and NUL padding ignored); None when the cell is
    /// not a finite number in this dialect. With a decimal comma, `0,365` and `2,02011E+13` are
    /// numbers and a decimal point is not accepted (it would be a thousands mark, or a mix).
    pub fn number(&self, cell: &str) -> Option<f64> {
        let t = clean(cell);
        let v = if self.decimal_comma {
            if t.contains('.') {
                return None;
            }
            t.replacen(',', ".", 1).parse::<f64>().ok()?
        } else {
            t.parse::<f64>().ok()?
        };
        v.is_finite().then_some(v)
    }
}

/// A cell's text without surrounding blanks or NUL padding.
pub fn clean(cell: &str) -> &str {
    cell.trim_matches(|c: char| c.is_whitespace() || c == '\0')
}

/// The bytes without a leading UTF-8 byte-order mark.
pub fn strip_bom(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes)
}

/// Lines looked at to detect a dialect.
const SAMPLE_LINES: usize = 50;

/// Why a dialect could not be detected.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Undetected {
    /// What was seen.
    pub reason: String,
}

/// Detects the separator (the candidate that splits the header and the first data lines into
/// the same number of fields, more than one; the most fields wins) and the decimal mark (a
/// decimal comma when the separator is not a comma and a data cell reads as a number with one).
pub fn detect(bytes: &[u8]) -> Result<Dialect, Undetected> {
    let text = String::from_utf8_lossy(strip_bom(bytes));
    let lines: Vec<&str> = text
        .split('\n')
        .map(|l| l.trim_end_matches(['\r', '\0', ' ']))
        .filter(|l| !l.is_empty())
        .take(SAMPLE_LINES)
        .collect();
    let Some(header) = lines.first() else {
        return Err(Undetected {
            reason: "the file is empty".into(),
        });
    };
    let best = [b',', b';', b'\t']
        .into_iter()
        .filter_map(|sep| {
            let n = fields(header, sep);
            let consistent = n > 1 && lines.iter().all(|l| fields(l, sep) == n);
            consistent.then_some((n, sep))
        })
        .max_by_key(|&(n, sep)| (n, sep == b';'));
    let Some((_, separator)) = best else {
        return Err(Undetected {
            reason: format!(
                "no separator among `,`, `;` and tab splits the header ({} fields with `,`, {} with `;`, {} with tab) and the first data lines alike",
                fields(header, b','),
                fields(header, b';'),
                fields(header, b'\t')
            ),
        });
    };
    let decimal_comma = separator != b','
        && lines.iter().skip(1).any(|l| {
            split(l, separator).any(|cell| {
                let c = clean(cell);
                c.contains(',') && Dialect::SEMICOLON_DECIMAL_COMMA.number(c).is_some()
            })
        });
    Ok(Dialect {
        separator,
        decimal_comma,
    })
}

/// Fields of a line split at `sep` outside double quotes.
fn split(line: &str, sep: u8) -> impl Iterator<Item = &str> {
    let mut quoted = false;
    let mut start = 0;
    let bytes = line.as_bytes();
    let mut cuts = Vec::new();
    for (i, &b) in bytes.iter().enumerate() {
        if b == b'"' {
            quoted = !quoted;
        } else if b == sep && !quoted {
            cuts.push((start, i));
            start = i + 1;
        }
    }
    cuts.push((start, bytes.len()));
    cuts.into_iter().map(move |(a, b)| &line[a..b])
}

fn fields(line: &str, sep: u8) -> usize {
    split(line, sep).count()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detects_separator_and_decimal_mark() {
        let ur =
            b"\xEF\xBB\xBFTimestamp;Goal x;q1\r\n2,02011E+13;0,365;-1,5708\r\n2,02011E+13;0,4;0";
        assert_eq!(detect(ur), Ok(Dialect::SEMICOLON_DECIMAL_COMMA));
        assert_eq!(detect(b"a,b,c\n1.5,2,3\n"), Ok(Dialect::COMMA));
        assert_eq!(detect(b"a;b;c\n1.5;2;3\n"), Ok(Dialect::SEMICOLON));
        assert_eq!(detect(b"a\tb\n1,5\t2\n"), Ok(Dialect::TAB_DECIMAL_COMMA));
        // Quoted separators do not count.
        assert_eq!(detect(b"a,b\n\"x,y\",2\n"), Ok(Dialect::COMMA));
        assert!(detect(b"justone\n1\n").is_err());
    }

    #[test]
    fn numbers_in_either_mark() {
        let d = Dialect::SEMICOLON_DECIMAL_COMMA;
        assert_eq!(d.number(" 0,365\0"), Some(0.365));
        assert_eq!(d.number("2,02011E+13"), Some(2.02011e13));
        assert_eq!(d.number("1.234,5"), None);
        assert_eq!(Dialect::COMMA.number("0,3"), None);
        assert_eq!(Dialect::COMMA.number("NaN"), None);
    }
}
