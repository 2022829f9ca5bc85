//! Timestamps of an imported file: seconds, `YYYYMMDDhhmmss` or ISO 8601 date-times, parsed
//! where they are valid; a column that is constant, or is not a time at all (a spreadsheet that
//! turned `20201118143000` into `2,02011E+13`), is reported as lost rather than handed on as a
//! constant time.

use super::dialect::{clean, Dialect};

/// How the time column is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TimeFormat {
    /// Decided from the column: `YYYYMMDDhhmmss` when every cell has 14 digits, ISO 8601 when
    /// every cell is a date-time, otherwise seconds.
    #[default]
    Auto,
    /// Seconds (any origin).
    Seconds,
    /// `YYYYMMDDhhmmss[.fff]`, a local time.
    Compact,
    /// ISO 8601 / RFC 3339: `YYYY-MM-DD[T| ]hh:mm:ss[.fff][Z|±hh:mm]`.
    Iso8601,
}

impl TimeFormat {
    /// The format's name as the CLI spells it.
    pub fn name(self) -> &'static str {
        match self {
            TimeFormat::Auto => "auto",
            TimeFormat::Seconds => "seconds",
            TimeFormat::Compact => "yyyymmddhhmmss",
            TimeFormat::Iso8601 => "iso8601",
        }
    }
}

/// What became of an imported file's time column.
#[derive(Debug, Clone, PartialEq)]
pub enum TimeStatus {
    /// No time column was named.
    NoColumn,
    /// Every row has a time.
    Kept {
        /// The format read.
        format: TimeFormat,
        /// The earliest time as ISO 8601 (date-time formats only).
        start: Option<String>,
    },
    /// Some rows have a time, the others could not be read as one.
    Partial {
        /// The format read.
        format: TimeFormat,
        /// The earliest time as ISO 8601 (date-time formats only).
        start: Option<String>,
        /// Rows without a valid time.
        lost_rows: usize,
        /// Rows in all.
        rows: usize,
        /// The first cell that is not a time.
        example: String,
    },
    /// No row has a usable time: `t_s` is left empty.
    Lost {
        /// Why, for a person.
        reason: String,
    },
}

impl TimeStatus {
    /// `none`, `kept`, `partial` or `lost`.
    pub fn keyword(&self) -> &'static str {
        match self {
            TimeStatus::NoColumn => "none",
            TimeStatus::Kept { .. } => "kept",
            TimeStatus::Partial { .. } => "partial",
            TimeStatus::Lost { .. } => "lost",
        }
    }
}

/// A time column read: per row the time in seconds (from the earliest row for date-times), and
/// what became of the column.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeColumn {
    /// Per row, seconds; None where the cell is not a time (or the column is lost).
    pub t_s: Vec<Option<f64>>,
    /// The column's fate.
    pub status: TimeStatus,
}

/// Reads the cells of a time column (one per row, as written).
pub fn read_times(cells: &[&str], format: TimeFormat, dialect: &Dialect) -> TimeColumn {
    let lost = |reason: String| TimeColumn {
        t_s: vec![None; cells.len()],
        status: TimeStatus::Lost { reason },
    };
    let cleaned: Vec<&str> = cells.iter().map(|c| clean(c)).collect();
    if cleaned.is_empty() {
        return lost("the file has no rows".into());
    }
    if cleaned.len() > 1 && cleaned.iter().all(|c| *c == cleaned[0]) {
        let why = if looks_mangled(cleaned[0], dialect) {
            ": a spreadsheet wrote a YYYYMMDDhhmmss time in scientific notation, which keeps only \
             the first digits; only the row order is left"
        } else {
            ""
        };
        return lost(format!("every row reads `{}`{why}", cleaned[0]));
    }
    let format = match format {
        TimeFormat::Auto => guess(&cleaned),
        f => f,
    };
    let parsed: Vec<Option<f64>> = cleaned
        .iter()
        .map(|c| match format {
            TimeFormat::Compact => compact(c),
            TimeFormat::Iso8601 => iso8601(c),
            _ => dialect.number(c),
        })
        .collect();
    let valid: Vec<f64> = parsed.iter().flatten().copied().collect();
    let example = cleaned
        .iter()
        .zip(&parsed)
        .find(|(_, p)| p.is_none())
        .map(|(c, _)| c.to_string());
    if valid.is_empty() {
        let c = cleaned[0];
        let why = if looks_mangled(c, dialect) {
            " (a YYYYMMDDhhmmss time a spreadsheet wrote in scientific notation)"
        } else {
            ""
        };
        return lost(format!(
            "no row holds a time as {} (first row `{c}`{why})",
            format.name()
        ));
    }
    if format == TimeFormat::Seconds && cleaned.iter().any(|c| looks_mangled(c, dialect)) {
        return lost(format!(
            "`{}` is a YYYYMMDDhhmmss time a spreadsheet wrote in scientific notation: the \
             seconds are gone; only the row order is left",
            cleaned
                .iter()
                .find(|c| looks_mangled(c, dialect))
                .copied()
                .unwrap_or("")
        ));
    }
    if valid.len() > 1 && valid.iter().all(|v| *v == valid[0]) {
        return lost(format!("every row holds the same time `{}`", cleaned[0]));
    }
    let dated = matches!(format, TimeFormat::Compact | TimeFormat::Iso8601);
    let origin = if dated {
        valid.iter().copied().fold(f64::INFINITY, f64::min)
    } else {
        0.0
    };
    let start = dated.then(|| iso_of(origin));
    let t_s = parsed.iter().map(|v| v.map(|v| v - origin)).collect();
    let lost_rows = parsed.iter().filter(|p| p.is_none()).count();
    let status = match example {
        Some(example) => TimeStatus::Partial {
            format,
            start,
            lost_rows,
            rows: parsed.len(),
            example,
        },
        None => TimeStatus::Kept { format, start },
    };
    TimeColumn { t_s, status }
}

/// The format most cells are in.
fn guess(cells: &[&str]) -> TimeFormat {
    let share = |f: &dyn Fn(&str) -> bool| cells.iter().filter(|c| f(c)).count() * 2 > cells.len();
    if share(&|c| compact(c).is_some()) {
        TimeFormat::Compact
    } else if share(&|c| iso8601(c).is_some()) {
        TimeFormat::Iso8601
    } else {
        TimeFormat::Seconds
    }
}

/// A number in scientific notation between 10¹³ and 10¹⁴: a 14-digit date-time cut to a few
/// digits by a spreadsheet.
fn looks_mangled(cell: &str, dialect: &Dialect) -> bool {
    cell.contains(['e', 'E'])
        && dialect
            .number(cell)
            .is_some_and(|v| (1e13..1e14).contains(&v))
}

/// Seconds since 1970-01-01 of `YYYYMMDDhhmmss[.fff]` (a naive local time).
fn compact(c: &str) -> Option<f64> {
    let (whole, frac) = c.split_once(['.', ',']).unwrap_or((c, ""));
    if whole.len() != 14 || !whole.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let n = |a: usize, b: usize| whole[a..b].parse::<u32>().ok();
    let s = seconds_of(
        n(0, 4)? as i64,
        n(4, 6)?,
        n(6, 8)?,
        n(8, 10)?,
        n(10, 12)?,
        n(12, 14)?,
    )?;
    Some(s + fraction(frac)?)
}

/// Seconds since 1970-01-01 UTC of an ISO 8601 date-time (a naive one taken as it is).
fn iso8601(c: &str) -> Option<f64> {
    let b = c.as_bytes();
    if b.len() < 19 || b[4] != b'-' || b[7] != b'-' || !matches!(b[10], b'T' | b't' | b' ') {
        return None;
    }
    if b[13] != b':' || b[16] != b':' {
        return None;
    }
    let n = |a: usize, e: usize| -> Option<u32> {
        let s = c.get(a..e)?;
        s.bytes()
            .all(|x| x.is_ascii_digit())
            .then(|| s.parse().ok())?
    };
    let mut s = seconds_of(
        n(0, 4)? as i64,
        n(5, 7)?,
        n(8, 10)?,
        n(11, 13)?,
        n(14, 16)?,
        n(17, 19)?,
    )?;
    let rest = &c[19..];
    let (frac, zone) = match rest.strip_prefix(['.', ',']) {
        Some(r) => {
            let k = r.find(|ch: char| !ch.is_ascii_digit()).unwrap_or(r.len());
            (&r[..k], &r[k..])
        }
        None => ("", rest),
    };
    s += fraction(frac)?;
    match zone {
        "" | "Z" | "z" => {}
        z => {
            let sign = match z.as_bytes().first() {
                Some(b'+') => 1.0,
                Some(b'-') => -1.0,
                _ => return None,
            };
            let hm = z[1..].replace(':', "");
            if hm.len() != 4 || !hm.bytes().all(|x| x.is_ascii_digit()) {
                return None;
            }
            let h: f64 = hm[..2].parse().ok()?;
            let m: f64 = hm[2..].parse().ok()?;
            s -= sign * (h * 3600.0 + m * 60.0);
        }
    }
    Some(s)
}

fn fraction(digits: &str) -> Option<f64> {
    if digits.is_empty() {
        return Some(0.0);
    }
    if !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    format!("0.{digits}").parse().ok()
}

/// Seconds since 1970-01-01 of a calendar date and time; None when it is not one.
fn seconds_of(y: i64, mo: u32, d: u32, h: u32, mi: u32, s: u32) -> Option<f64> {
    let leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
    let days_in = [
        31,
        if leap { 29 } else { 28 },
        31,
        30,
        31,
        30,
        31,
        31,
        30,
        31,
        30,
        31,
    ];
    if !(1..=12).contains(&mo) || d == 0 || d > days_in[(mo - 1) as usize] {
        return None;
    }
    if h > 23 || mi > 59 || s > 60 {
        return None;
    }
    Some((days_from_civil(y, mo, d) * 86_400 + (h * 3600 + mi * 60 + s) as i64) as f64)
}

/// Days since 1970-01-01 (Howard Hinnant's algorithm).
fn days_from_civil(y: i64, m: u32, d: u32) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m as i64 + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d as i64 - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// `YYYY-MM-DDThh:mm:ss` of seconds since 1970-01-01 UTC (whole seconds; the civil date from
/// the day count, H. Hinnant's `civil_from_days`). Session lock files and start times use it too.
pub fn iso_of(t: f64) -> String {
    let secs = t.floor() as i64;
    let days = secs.div_euclid(86_400);
    let rem = secs.rem_euclid(86_400);
    // Inverse of days_from_civil.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    const DC: Dialect = Dialect::SEMICOLON_DECIMAL_COMMA;

    #[test]
    fn compact_times_are_kept_from_the_earliest() {
        let c = read_times(
            &["20200714163904", "20200714163924", "20200714163900"],
            TimeFormat::Auto,
            &DC,
        );
        assert_eq!(c.t_s, vec![Some(4.0), Some(24.0), Some(0.0)]);
        assert_eq!(
            c.status,
            TimeStatus::Kept {
                format: TimeFormat::Compact,
                start: Some("2020-07-14T16:39:00".into())
            }
        );
    }

    #[test]
    fn a_constant_or_mangled_column_is_lost() {
        let c = read_times(&["2,02011E+13"; 3], TimeFormat::Auto, &DC);
        assert!(c.t_s.iter().all(Option::is_none));
        let TimeStatus::Lost { reason } = c.status else {
            panic!("{:?}", c.status)
        };
        assert!(reason.contains("every row reads `2,02011E+13`"), "{reason}");
        assert!(reason.contains("scientific notation"), "{reason}");
        let c = read_times(&["2,02011E+13", "2,02012E+13"], TimeFormat::Auto, &DC);
        assert_eq!(c.status.keyword(), "lost", "{:?}", c.status);
        let c = read_times(&["noon", "later"], TimeFormat::Auto, &DC);
        assert_eq!(c.status.keyword(), "lost");
    }

    #[test]
    fn seconds_iso_and_partial_columns() {
        let c = read_times(&["0,5", "1,5"], TimeFormat::Auto, &DC);
        assert_eq!(c.t_s, vec![Some(0.5), Some(1.5)]);
        let c = read_times(
            &[
                "2021-03-01T10:00:00+01:00",
                "2021-03-01 09:00:30Z",
                "2021-02-30T00:00:00",
            ],
            TimeFormat::Auto,
            &DC,
        );
        assert_eq!(c.t_s, vec![Some(0.0), Some(30.0), None]);
        let TimeStatus::Partial {
            lost_rows: 1,
            example,
            ..
        } = &c.status
        else {
            panic!("{:?}", c.status)
        };
        assert_eq!(example, "2021-02-30T00:00:00");
        assert_eq!(iso_of(0.0), "1970-01-01T00:00:00");
        assert_eq!(
            iso_of(compact("20000229235959").unwrap()),
            "2000-02-29T23:59:59"
        );
    }
}
