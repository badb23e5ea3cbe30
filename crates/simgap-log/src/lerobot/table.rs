//! The Parquet files of a LeRobot dataset, read column by column: the only file of the crate
//! that names the `parquet` crate.
//!
//! A column is read by its top-level name (`observation.state`, `frame_index`, …): it must be
//! one leaf, a number (`FLOAT`, `DOUBLE`, `INT32`, `INT64`) or a list of numbers (Arrow's
//! `list` and `fixed_size_list` are both a Parquet `LIST`), without nulls. Everything else in
//! the file (the `stats/…` columns of an episodes file, images, strings) is never decoded.
//!
//! Row groups can be skipped by the statistics of an integer column ([`RowGroups`]), so that
//! reading one episode of a v3.0 file (one row group per episode, as LeRobot writes it) decodes
//! that episode only.
//!
//! Nothing here trusts a count the file declares: vectors grow with the values actually
//! decoded, a row group that ends before its declared rows is an error, and a panic inside the
//! decoder (a bug there) is caught by the reader's guard like any other.

use std::collections::BTreeMap;
use std::fs::File;
use std::path::Path;

use parquet::basic::Type as PhysicalType;
use parquet::column::reader::ColumnReader;
use parquet::file::reader::{FileReader, RowGroupReader, SerializedFileReader};
use parquet::file::statistics::Statistics;

/// The most values one column of one file may hold (2²⁸ numbers, 2 GiB as f64): far above any
/// episode file (LeRobot cuts data files at 100 MB), and a bound on what a hostile file can
/// make the reader allocate.
pub(crate) const MAX_VALUES: usize = 1 << 28;

/// Records decoded per call of the column reader.
const BATCH: usize = 8192;

/// A column as read: numbers per row (`width` 1 for a scalar column), row-major.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Column {
    /// Values per row (1 for a scalar).
    pub(crate) width: usize,
    /// `rows × width` numbers.
    pub(crate) values: Vec<f64>,
    /// Whether the file stores integers (`INT32`/`INT64`) rather than floats.
    pub(crate) integer: bool,
    /// Whether the column is a list (even of one value).
    pub(crate) list: bool,
}

/// Some columns of a file, over the row groups read.
#[derive(Clone, Debug, Default)]
pub(crate) struct Table {
    /// Rows read.
    pub(crate) rows: usize,
    /// The columns asked for, by name.
    pub(crate) columns: BTreeMap<String, Column>,
}

impl Table {
    /// The column `name` (present when it was asked for and not optional-and-absent).
    pub(crate) fn column(&self, name: &str) -> Option<&Column> {
        self.columns.get(name)
    }
}

/// Which row groups to read.
#[derive(Clone, Debug)]
pub(crate) enum RowGroups {
    /// Every row group.
    All,
    /// Row groups whose statistics of the integer column `column` allow one of `values`
    /// (row groups without statistics are read).
    Containing { column: String, values: Vec<i64> },
}

/// What a column is, from its leaf in the schema.
struct Leaf {
    index: usize,
    physical: PhysicalType,
    max_def: i16,
    max_rep: i16,
}

/// Opens a Parquet file.
fn open(path: &Path) -> Result<SerializedFileReader<File>, String> {
    let file = File::open(path).map_err(|e| format!("cannot open: {e}"))?;
    SerializedFileReader::new(file).map_err(|e| format!("not a readable Parquet file: {}", parquet_message(&e)))
}

/// A Parquet error as a sentence (a codec left out of this build named as such).
fn parquet_message(e: &parquet::errors::ParquetError) -> String {
    let s = e.to_string();
    if s.contains("Disabled feature") || s.contains("not supported") && s.to_lowercase().contains("codec") {
        format!("{s} (simgap reads Parquet compressed with snappy, zstd or gzip, or uncompressed)")
    } else {
        s
    }
}

/// The leaf column of the top-level field `name`, if the file has one.
fn leaf(reader: &SerializedFileReader<File>, name: &str) -> Result<Option<Leaf>, String> {
    let schema = reader.metadata().file_metadata().schema_descr();
    let leaves: Vec<usize> = (0..schema.num_columns()).filter(|&i| schema.column(i).path().parts().first().map(String::as_str) == Some(name)).collect();
    match leaves.as_slice() {
        [] => Ok(None),
        [i] => {
            let c = schema.column(*i);
            if !c.self_type().is_primitive() {
                return Err(format!("column '{name}' is not a column of numbers"));
            }
            Ok(Some(Leaf { index: *i, physical: c.physical_type(), max_def: c.max_def_level(), max_rep: c.max_rep_level() }))
        }
        many => Err(format!("column '{name}' is a nested record of {} fields; expected numbers or a list of numbers", many.len())),
    }
}

/// Whether row group `rg` may hold a row of `rows`.
fn wanted(reader: &SerializedFileReader<File>, rg: usize, rows: &RowGroups, index_column: Option<usize>) -> bool {
    let RowGroups::Containing { values, .. } = rows else { return true };
    let Some(i) = index_column else { return true };
    let meta = reader.metadata().row_group(rg);
    let (lo, hi) = match meta.column(i).statistics() {
        Some(Statistics::Int64(s)) => (s.min_opt().copied(), s.max_opt().copied()),
        Some(Statistics::Int32(s)) => (s.min_opt().map(|v| i64::from(*v)), s.max_opt().map(|v| i64::from(*v))),
        _ => (None, None),
    };
    match (lo, hi) {
        (Some(lo), Some(hi)) => values.iter().any(|v| (lo..=hi).contains(v)),
        _ => true,
    }
}

/// Reads the columns `names` of a Parquet file, over the row groups `rows` selects. A name in
/// `optional` that the file lacks is left out; any other missing name is an error.
///
/// # Errors
/// A message (the caller adds the file): the file is not Parquet or is cut or corrupt, a column
/// is missing, is not numbers or a list of numbers, holds nulls, has rows of unequal length,
/// or holds more than [`MAX_VALUES`] numbers.
pub(crate) fn read_columns(path: &Path, names: &[&str], optional: &[&str], rows: &RowGroups) -> Result<Table, String> {
    let reader = open(path)?;
    // the leaves of the columns asked for
    let mut leaves: Vec<(&str, Leaf)> = Vec::new();
    for &name in names {
        match leaf(&reader, name)? {
            Some(l) => leaves.push((name, l)),
            None if optional.contains(&name) => {}
            None => return Err(format!("has no column '{name}'")),
        }
    }
    for (name, l) in &leaves {
        if !matches!(l.physical, PhysicalType::FLOAT | PhysicalType::DOUBLE | PhysicalType::INT32 | PhysicalType::INT64) {
            return Err(format!("column '{name}' holds {:?} values; expected numbers (float, double or integer)", l.physical));
        }
        if l.max_rep > 1 {
            return Err(format!("column '{name}' is a list of lists; expected numbers or a list of numbers"));
        }
    }
    let index_column = match rows {
        RowGroups::Containing { column, .. } => leaf(&reader, column)?.map(|l| l.index),
        RowGroups::All => None,
    };
    // row group by row group, column by column
    let mut table = Table::default();
    let mut columns: Vec<Column> = leaves
        .iter()
        .map(|(_, l)| Column { width: 0, values: Vec::new(), integer: matches!(l.physical, PhysicalType::INT32 | PhysicalType::INT64), list: l.max_rep == 1 })
        .collect();
    for rg in 0..reader.num_row_groups() {
        if !wanted(&reader, rg, rows, index_column) {
            continue;
        }
        let group = reader.get_row_group(rg).map_err(|e| format!("row group {rg}: {}", parquet_message(&e)))?;
        let declared = group.metadata().num_rows();
        let declared = usize::try_from(declared).map_err(|_| format!("row group {rg} declares {declared} rows"))?;
        for ((name, l), column) in leaves.iter().zip(columns.iter_mut()) {
            read_leaf(group.as_ref(), l, declared, column).map_err(|m| format!("column '{name}', row group {rg}: {m}"))?;
        }
        table.rows += declared;
    }
    for ((name, _), column) in leaves.iter().zip(columns) {
        table.columns.insert(name.to_string(), column);
    }
    Ok(table)
}

/// Appends the `rows` rows of one leaf in one row group to `out`.
fn read_leaf(group: &dyn RowGroupReader, l: &Leaf, rows: usize, out: &mut Column) -> Result<(), String> {
    let reader = group.get_column_reader(l.index).map_err(|e| parquet_message(&e))?;
    let (mut def, mut rep) = (Vec::new(), Vec::new());
    let start = out.values.len();
    let mut read = 0;
    macro_rules! drain {
        ($r:expr, $convert:expr) => {{
            let mut r = $r;
            let mut buf = Vec::new();
            while read < rows {
                buf.clear();
                def.clear();
                let (records, values, levels) = r.read_records((rows - read).min(BATCH), Some(&mut def), Some(&mut rep), &mut buf).map_err(|e| parquet_message(&e))?;
                if records == 0 && values == 0 && levels == 0 {
                    return Err(format!("ends after {read} of its {rows} rows (the file is cut or corrupt)"));
                }
                // a value for every level: no null, no empty list
                let levels_read = if l.max_def > 0 { def.len() } else { levels.max(values) };
                if values != levels_read || buf.len() != values {
                    return Err("holds null values; expected a number in every row".into());
                }
                if out.values.len() - start + values > MAX_VALUES {
                    return Err(format!("holds more than {MAX_VALUES} numbers"));
                }
                out.values.extend(buf.iter().map($convert));
                read += records;
            }
        }};
    }
    match reader {
        ColumnReader::FloatColumnReader(r) => drain!(r, |v: &f32| f64::from(*v)),
        ColumnReader::DoubleColumnReader(r) => drain!(r, |v: &f64| *v),
        ColumnReader::Int32ColumnReader(r) => drain!(r, |v: &i32| f64::from(*v)),
        ColumnReader::Int64ColumnReader(r) => drain!(r, |v: &i64| *v as f64),
        _ => return Err("is not a column of numbers".into()),
    }
    if read != rows {
        return Err(format!("holds {read} rows; the row group declares {rows}"));
    }
    // rows of a list: each starts at repetition level 0, and all have one width
    let values = out.values.len() - start;
    let width = if l.max_rep == 0 {
        1
    } else {
        let mut width: Option<usize> = None;
        let mut count = 0usize;
        for (k, &r) in rep.iter().enumerate() {
            if r == 0 && k > 0 {
                check_width(&mut width, count)?;
                count = 0;
            }
            count += 1;
        }
        if !rep.is_empty() {
            check_width(&mut width, count)?;
        }
        width.unwrap_or(0)
    };
    if values != rows * width {
        return Err(format!("holds {values} numbers in {rows} rows; expected {width} per row"));
    }
    if out.width != 0 && rows > 0 && out.width != width {
        return Err(format!("has {width} numbers per row here and {} in an earlier row group", out.width));
    }
    if rows > 0 {
        out.width = width;
    }
    Ok(())
}

/// Records a list's length, which every row must share.
fn check_width(width: &mut Option<usize>, count: usize) -> Result<(), String> {
    match *width {
        None => {
            *width = Some(count);
            Ok(())
        }
        Some(w) if w == count => Ok(()),
        Some(w) => Err(format!("has lists of {w} and of {count} numbers; expected one length in every row")),
    }
}
