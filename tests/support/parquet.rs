//! The Parquet tables nlstudy writes, read back (a module of the test files that read tables:
//! polars is a dev-dependency, out of the support library).

use polars::prelude::{DataFrame, DataType, ParquetReader, SerReader};
use std::path::Path;

/// A column of a Parquet table as floats (null as NaN).
pub fn floats(frame: &DataFrame, name: &str) -> Vec<f64> {
    let column = frame.column(name).unwrap_or_else(|e| panic!("{name}: {e}"));
    let column = column.cast(&DataType::Float64).unwrap();
    let floats = column.f64().unwrap();
    (0..floats.len())
        .map(|i| floats.get(i).unwrap_or(f64::NAN))
        .collect()
}

pub fn read_parquet(path: &Path) -> DataFrame {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    ParquetReader::new(file).finish().expect("a Parquet file")
}
