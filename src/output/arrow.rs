//! Apache Arrow IPC file format (Feather v2) output: one `Float64` column per
//! output column, its unit in the field metadata, rows buffered column-wise
//! and written as record batches of at most [`BATCH_VALUES`] values.

use std::collections::HashMap;
use std::io::Write;
use std::sync::Arc;

use arrow_array::{ArrayRef, Float64Array, RecordBatch};
use arrow_ipc::writer::FileWriter;
use arrow_schema::{DataType, Field, Schema};

use super::{Column, TableError, TableWriter};

/// Values buffered before a record batch is written (8 MB of `f64`): the
/// memory of the writer, whatever the number of rows.
pub(crate) const BATCH_VALUES: usize = 1 << 20;

/// An Arrow IPC file written row by row, read by pyarrow
/// (`pyarrow.ipc.open_file`, `pyarrow.feather.read_table`), polars, R's
/// arrow and DuckDB.
pub struct ArrowTable<W: Write> {
    w: Option<FileWriter<W>>,
    schema: Arc<Schema>,
    /// One buffer per column, `batch_rows` capacity.
    buffers: Vec<Vec<f64>>,
    batch_rows: usize,
    finished: bool,
}

fn arrow_err(e: arrow_schema::ArrowError) -> TableError {
    match e {
        arrow_schema::ArrowError::IoError(_, io) => TableError::Io(io),
        e => TableError::Arrow(e.to_string()),
    }
}

impl<W: Write> ArrowTable<W> {
    /// Write the file header and schema of `columns` to `w`.
    pub fn new(w: W, columns: &[Column]) -> Result<Self, TableError> {
        let fields: Vec<Field> = columns
            .iter()
            .map(|c| {
                Field::new(&c.name, DataType::Float64, false)
                    .with_metadata(HashMap::from([("unit".to_string(), c.unit.to_string())]))
            })
            .collect();
        let schema = Arc::new(Schema::new(fields));
        let w = FileWriter::try_new(w, &schema).map_err(arrow_err)?;
        let batch_rows = (BATCH_VALUES / columns.len().max(1)).max(1);
        Ok(Self {
            w: Some(w),
            schema,
            buffers: (0..columns.len())
                .map(|_| Vec::with_capacity(batch_rows))
                .collect(),
            batch_rows,
            finished: false,
        })
    }

    /// Rows per full record batch.
    pub fn batch_rows(&self) -> usize {
        self.batch_rows
    }

    fn write_batch(&mut self) -> Result<(), TableError> {
        let w = self.w.as_mut().ok_or(TableError::Finished)?;
        if self.buffers.first().is_none_or(|b| b.is_empty()) {
            return Ok(());
        }
        let arrays: Vec<ArrayRef> = self
            .buffers
            .iter_mut()
            .map(|b| {
                let full = std::mem::replace(b, Vec::with_capacity(self.batch_rows));
                Arc::new(Float64Array::from(full)) as ArrayRef
            })
            .collect();
        let batch = RecordBatch::try_new(self.schema.clone(), arrays)
            .map_err(|e| TableError::Arrow(e.to_string()))?;
        w.write(&batch).map_err(arrow_err)
    }

    /// The underlying writer, after [`TableWriter::finish`].
    pub fn into_inner(mut self) -> Option<W> {
        self.w.take().and_then(|w| w.into_inner().ok())
    }
}

impl<W: Write> TableWriter for ArrowTable<W> {
    fn write_row(&mut self, row: &[f64]) -> Result<(), TableError> {
        if row.len() != self.buffers.len() {
            return Err(TableError::RowLength {
                expected: self.buffers.len(),
                got: row.len(),
            });
        }
        if self.finished {
            return Err(TableError::Finished);
        }
        for (b, v) in self.buffers.iter_mut().zip(row) {
            b.push(*v);
        }
        if self.buffers.first().map_or(0, Vec::len) >= self.batch_rows {
            self.write_batch()?;
        }
        Ok(())
    }

    fn flush(&mut self) -> Result<(), TableError> {
        if self.finished {
            return Ok(());
        }
        self.write_batch()?;
        if let Some(w) = self.w.as_mut() {
            w.flush().map_err(arrow_err)?;
        }
        Ok(())
    }

    fn finish(&mut self) -> Result<(), TableError> {
        if self.finished {
            return Ok(());
        }
        self.write_batch()?;
        self.finished = true;
        let w = self.w.as_mut().ok_or(TableError::Finished)?;
        w.finish().map_err(arrow_err)?;
        w.flush().map_err(arrow_err)
    }
}

/// The leading magic of the Arrow IPC file format; zero padding to the
/// writer's alignment (8 or 64 bytes) and the IPC stream (schema, then
/// record batches) follow it.
const MAGIC: &[u8; 6] = b"ARROW1";

/// Recover the complete record batches of an Arrow IPC file whose writer
/// was killed before its footer (a run's `.arrow.part`): everything after
/// the magic and its padding is an IPC stream; its batches are read until
/// the end or the first incomplete message and written to `w` as a
/// finished IPC file. Returns the rows recovered.
pub fn recover<R: std::io::Read, W: Write>(r: R, w: W) -> Result<usize, TableError> {
    use std::io::{BufRead, Read};
    let mut r = std::io::BufReader::new(r);
    let mut magic = [0u8; 6];
    r.read_exact(&mut magic)?;
    if &magic != MAGIC {
        return Err(TableError::Arrow(
            "not an Arrow IPC file (no ARROW1 magic at the start)".into(),
        ));
    }
    // the padding: zeros up to the first message's continuation marker
    loop {
        let buf = r.fill_buf()?;
        let zeros = buf.iter().take_while(|&&b| b == 0).count();
        let (len, done) = (buf.len(), zeros < buf.len());
        r.consume(zeros);
        if done || len == 0 {
            break;
        }
    }
    let reader = arrow_ipc::reader::StreamReader::try_new(r, None).map_err(arrow_err)?;
    let mut out = FileWriter::try_new(w, &reader.schema()).map_err(arrow_err)?;
    let mut rows = 0;
    // a killed writer's last message is cut short: stop at the first error
    for batch in reader.map_while(Result::ok) {
        rows += batch.num_rows();
        out.write(&batch).map_err(arrow_err)?;
    }
    out.finish().map_err(arrow_err)?;
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;
    use arrow_array::Array;
    use arrow_ipc::reader::FileReader;

    /// Rows written across several batches read back exactly (bit for bit,
    /// NaN included) by arrow's own reader, with names and units.
    #[test]
    fn round_trip_across_batches() {
        let ncols = 3000; // 349 rows per batch
        let cols: Vec<Column> = (0..ncols)
            .map(|k| Column::new(format!("c{k}"), if k == 0 { "s" } else { "m" }))
            .collect();
        let mut t = ArrowTable::new(Vec::new(), &cols).unwrap();
        let rows = 2 * t.batch_rows() + 17;
        let value = |r: usize, c: usize| {
            if (r, c) == (5, 7) {
                f64::NAN
            } else {
                (r as f64) * 1e-3 + (c as f64).sqrt() * 1e7
            }
        };
        let mut row = vec![0.0; ncols];
        for r in 0..rows {
            for (c, v) in row.iter_mut().enumerate() {
                *v = value(r, c);
            }
            t.write_row(&row).unwrap();
            if r == 10 {
                t.flush().unwrap(); // a short batch
            }
        }
        t.finish().unwrap();
        assert!(matches!(t.write_row(&row), Err(TableError::Finished)));
        let bytes = t.into_inner().unwrap();
        let reader = FileReader::try_new(std::io::Cursor::new(bytes), None).unwrap();
        let schema = reader.schema();
        assert_eq!(schema.fields().len(), ncols);
        assert_eq!(schema.field(0).metadata()["unit"], "s");
        assert_eq!(schema.field(12).name(), "c12");
        let mut r0 = 0;
        for batch in reader {
            let batch = batch.unwrap();
            for c in [0, 7, 12, ncols - 1] {
                let a = batch
                    .column(c)
                    .as_any()
                    .downcast_ref::<Float64Array>()
                    .unwrap();
                for i in 0..a.len() {
                    assert_eq!(a.value(i).to_bits(), value(r0 + i, c).to_bits());
                }
            }
            r0 += batch.num_rows();
        }
        assert_eq!(r0, rows);
    }

    /// A file cut anywhere after its first flushed batch (a killed writer)
    /// gives back exactly its complete batches.
    #[test]
    fn recover_cut_file() {
        let cols: Vec<Column> = (0..3).map(|k| Column::new(format!("c{k}"), "m")).collect();
        let mut t = ArrowTable::new(Vec::new(), &cols).unwrap();
        for r in 0..10 {
            t.write_row(&[r as f64, 1.0, 2.0]).unwrap();
        }
        t.flush().unwrap();
        for r in 10..25 {
            t.write_row(&[r as f64, 1.0, 2.0]).unwrap();
        }
        t.flush().unwrap();
        t.finish().unwrap();
        let bytes = t.into_inner().unwrap();
        // every cut: an error (schema cut) or exactly the complete batches,
        // never fewer with more bytes
        let mut last = 0;
        let mut seen = std::collections::BTreeSet::new();
        for cut in 6..=bytes.len() {
            let mut out = Vec::new();
            let Ok(rows) = recover(&bytes[..cut], &mut out) else {
                assert_eq!(last, 0, "cut at {cut}: an error after rows");
                continue;
            };
            assert!(
                [0, 10, 25].contains(&rows) && rows >= last,
                "cut at {cut}: {rows}"
            );
            last = rows;
            if seen.insert(rows) {
                let reader = FileReader::try_new(std::io::Cursor::new(out), None).unwrap();
                let mut t = Vec::new();
                for b in reader {
                    let b = b.unwrap();
                    let a = b.column(0).as_any().downcast_ref::<Float64Array>().unwrap();
                    t.extend((0..a.len()).map(|i| a.value(i)));
                }
                assert_eq!(t, (0..rows).map(|r| r as f64).collect::<Vec<_>>());
            }
        }
        assert_eq!(seen.into_iter().collect::<Vec<_>>(), [0, 10, 25]);
        assert!(recover(&b"PAR1xxxxxxxx"[..], Vec::new()).is_err());
        assert!(recover(&b"ARROW1"[..], Vec::new()).is_err());
    }
}
