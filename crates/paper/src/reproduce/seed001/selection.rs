//! Which of seed 001's tables and figures to reproduce, running them, and writing them to a
//! directory (tables as text, Fig. 7 as CSV and SVG).

use super::{fig7, table11, table18, table5, table7, Fig7, ReproOptions, Table};
use rigcal_model::neural::NeuralError;
use rigcal_model::report::{plot_log_curves, CurvePanel, PathError};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Tables reproduced, each named by the table that carries its main numbers.
pub const REPRODUCED_TABLES: [u32; 4] = [5, 7, 11, 18];

/// Figures reproduced.
pub const REPRODUCED_FIGURES: [u32; 1] = [7];

/// Why a reproduction could not be run or written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReproduceError {
    /// The table number is not one the paper's reproductions cover.
    #[error("table {0} is not reproduced: use 5, 7, 11, 12, 17 or 18")]
    UnknownTable(u32),
    /// The figure number is not one the paper's reproductions cover.
    #[error("figure {0} is not reproduced: use 7")]
    UnknownFigure(u32),
    /// Training a network failed.
    #[error(transparent)]
    Neural(#[from] NeuralError),
    /// A file could not be written.
    #[error("cannot write {}: {source}", path.display())]
    Write {
        /// The file or directory.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The plot could not be drawn.
    #[error(transparent)]
    Plot(#[from] PathError),
}

/// The reproduced table that carries `table`'s numbers (4 is printed with 5, 6 and 8 with 7,
/// 10 and 12 with 11, 16 and 17 with 18).
pub fn reproduced_table(table: u32) -> Result<u32, ReproduceError> {
    match table {
        4 | 5 => Ok(5),
        6..=8 => Ok(7),
        10..=12 => Ok(11),
        16..=18 => Ok(18),
        other => Err(ReproduceError::UnknownTable(other)),
    }
}

/// The reproduced tables that carry `asked`, each once, in the order first asked.
pub fn tables_for(asked: &[u32]) -> Result<Vec<u32>, ReproduceError> {
    let mut keys = Vec::new();
    for &t in asked {
        let key = reproduced_table(t)?;
        if !keys.contains(&key) {
            keys.push(key);
        }
    }
    Ok(keys)
}

/// Checks that every figure asked for is reproduced.
pub fn check_figures(asked: &[u32]) -> Result<(), ReproduceError> {
    match asked.iter().find(|f| !REPRODUCED_FIGURES.contains(f)) {
        Some(&f) => Err(ReproduceError::UnknownFigure(f)),
        None => Ok(()),
    }
}

/// Runs one reproduced table (`key` from [`reproduced_table`]); `hidden` is the hidden-neuron
/// count of the Stewart platform and the 3-DOF SCARA. Returns the table and how long it took.
pub fn run_table(
    key: u32,
    o: &ReproOptions,
    hidden: usize,
) -> Result<(Table, Duration), ReproduceError> {
    let start = Instant::now();
    let table = match key {
        5 => table5(o)?,
        7 => table7(o)?,
        11 => table11(o, hidden)?,
        18 => table18(o, hidden)?,
        other => return Err(ReproduceError::UnknownTable(other)),
    };
    Ok((table, start.elapsed()))
}

/// Writes a table's text to `dir/seed001-table-KEY.txt`.
pub fn write_table(dir: &Path, key: u32, text: &str) -> Result<PathBuf, ReproduceError> {
    let file = dir.join(format!("seed001-table-{key}.txt"));
    std::fs::write(&file, text).map_err(|source| ReproduceError::Write {
        path: file.clone(),
        source,
    })?;
    Ok(file)
}

/// Runs Fig. 7, returning it and how long it took.
pub fn run_fig7(o: &ReproOptions) -> Result<(Fig7, Duration), ReproduceError> {
    let start = Instant::now();
    let fig = fig7(o)?;
    Ok((fig, start.elapsed()))
}

/// Writes Fig. 7 as `dir/seed001-fig7.csv` and an SVG of three log-log panels,
/// `dir/seed001-fig7.svg`; returns (svg, csv).
pub fn write_fig7(fig: &Fig7, dir: &Path) -> Result<(PathBuf, PathBuf), ReproduceError> {
    let csv = dir.join("seed001-fig7.csv");
    std::fs::write(&csv, fig.csv()).map_err(|source| ReproduceError::Write {
        path: csv.clone(),
        source,
    })?;
    let panels: Vec<CurvePanel> = fig
        .cases
        .iter()
        .enumerate()
        .map(|(c, curves)| CurvePanel {
            title: format!("case {}", c + 1),
            curves: curves
                .iter()
                .map(|k| {
                    (
                        format!("scheme {}", k.scheme),
                        k.points.iter().map(|&(i, e)| (i as f64, e)).collect(),
                    )
                })
                .collect(),
        })
        .collect();
    let svg = dir.join("seed001-fig7.svg");
    plot_log_curves(
        &svg,
        "Seed 001 Fig. 7: mean validation error during training (2-DOF SCARA)",
        "Levenberg–Marquardt iteration",
        "mean validation error (mm)",
        &panels,
    )?;
    Ok((svg, csv))
}

/// Reproduces the tables that carry `tables` and the figures of `figures` (all of them when
/// both are empty), `hidden` neurons for the networks the paper does not size, telling `say`
/// each one's text with how long it took; with `out`, each is also written there.
pub fn reproduce(
    tables: &[u32],
    figures: &[u32],
    o: &ReproOptions,
    hidden: usize,
    out: Option<&Path>,
    say: &mut dyn FnMut(&str),
) -> Result<(), ReproduceError> {
    let (tables, figures) = if tables.is_empty() && figures.is_empty() {
        (REPRODUCED_TABLES.to_vec(), REPRODUCED_FIGURES.to_vec())
    } else {
        (tables_for(tables)?, figures.to_vec())
    };
    check_figures(&figures)?;
    if let Some(dir) = out {
        std::fs::create_dir_all(dir).map_err(|source| ReproduceError::Write {
            path: dir.to_path_buf(),
            source,
        })?;
    }
    for key in tables {
        let (table, took) = run_table(key, o, hidden)?;
        let text = table.render();
        say(&format!("{text}  ({:.1} s)\n\n", took.as_secs_f64()));
        if let Some(dir) = out {
            write_table(dir, key, &text)?;
        }
    }
    if figures.contains(&7) {
        let (fig, took) = run_fig7(o)?;
        say(&format!(
            "{}  ({:.1} s)\n\n",
            fig.render(),
            took.as_secs_f64()
        ));
        if let Some(dir) = out {
            let (svg, csv) = write_fig7(&fig, dir)?;
            say(&format!(
                "plot: {}  data: {}\n",
                svg.display(),
                csv.display()
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn companion_tables_map_to_the_table_that_prints_them() {
        assert_eq!(
            tables_for(&[4, 5, 6, 12, 17, 8]).unwrap(),
            vec![5, 7, 11, 18]
        );
        assert!(matches!(
            reproduced_table(9),
            Err(ReproduceError::UnknownTable(9))
        ));
        assert!(check_figures(&[7]).is_ok());
        assert!(matches!(
            check_figures(&[7, 3]),
            Err(ReproduceError::UnknownFigure(3))
        ));
    }
}
