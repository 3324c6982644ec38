//! Output tables: a run's rows written as the integration delivers them,
//! in bounded memory, to any [`std::io::Write`] — CSV ([`CsvTable`]) or,
//! with the `arrow` feature, Apache Arrow IPC ([`ArrowTable`], columnar
//! binary for runs of 10⁴+ columns). A [`TableWriter`] takes the column
//! names and units once and then one row of `f64` values at a time; it
//! knows nothing of files: atomic renames, summaries and signals belong to
//! the application (the `mbsolve` binary).

#[cfg(feature = "arrow")]
mod arrow;
pub mod metrics;

#[cfg(feature = "arrow")]
pub use arrow::{recover as recover_arrow, ArrowTable};

use std::borrow::Cow;
use std::io::Write;

use crate::model::{
    drives, evaluate_sensors, joint_short_name, Drive, ReactionMap, Sensor, System,
};
use crate::simulation::{OutputQuantities, Sample};
use crate::words::from_words;

/// One output column: its name (`t`, `x1`, `B.fx`, …) and SI unit.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Column {
    /// Column name.
    pub name: String,
    /// Unit, e.g. `"m"`, `"rad/s"`, `"N m"`, `""` for none; a controller
    /// state's is the scenario's text ([`crate::model::State::unit`]).
    pub unit: Cow<'static, str>,
}

impl Column {
    /// A column named `name` in `unit`.
    pub fn new(name: impl Into<String>, unit: impl Into<Cow<'static, str>>) -> Self {
        Self {
            name: name.into(),
            unit: unit.into(),
        }
    }
}

/// The columns of a run's table: `t`, per body `B.x,B.y,B.phi`
/// ([`body_labels`]: `crank.x`, `rod.segment[5].y`), each controller state
/// by its name in its unit ([`crate::model::State`]), `constraint_norm`,
/// then what `o` selects: velocities `B.vx,B.vy,B.omega`, accelerations
/// `B.ax,B.ay,B.alpha`, per joint `J.fx,J.fy,J.mz` (reaction
/// on its body, global frame, moment about the centre of mass) and
/// `J.fx_local,J.fy_local` (in that body's frame) and the joint's
/// multipliers `J.lambda1,…`, per drive `J.drive`
/// (its generalized force −λ, [`Drive::force`]), the energies
/// ([`ENERGY_COLUMNS`]); then per sensor `S.QUANTITY`
/// ([`Sensor::quantities`]). The positional names of earlier versions
/// (`x1`, `phi3`, `vx2`, …) are still found by [`find_column`].
pub fn columns(sys: &System, o: &OutputQuantities, sensors: &[Sensor]) -> Vec<Column> {
    let labels = body_labels(sys);
    let mut c = vec![Column::new("t", "s")];
    let per_body = |c: &mut Vec<Column>, names: [&str; 3], units: [&'static str; 3]| {
        for b in &labels {
            for (n, u) in names.iter().zip(units) {
                c.push(Column::new(format!("{b}.{n}"), u));
            }
        }
    };
    per_body(&mut c, POSITION, ["m", "m", "rad"]);
    for s in sys.states() {
        c.push(Column::new(&s.name, s.unit.clone()));
    }
    c.push(Column::new("constraint_norm", "m"));
    if o.velocities {
        per_body(&mut c, VELOCITY, ["m/s", "m/s", "rad/s"]);
    }
    if o.accelerations {
        per_body(&mut c, ACCELERATION, ["m/s^2", "m/s^2", "rad/s^2"]);
    }
    if o.reactions {
        let map = sys.reaction_map();
        for k in 0..sys.constraints().len() {
            let j = joint_label(sys, k);
            for (n, u) in [
                ("fx", "N"),
                ("fy", "N"),
                ("mz", "N m"),
                ("fx_local", "N"),
                ("fy_local", "N"),
            ] {
                c.push(Column::new(format!("{j}.{n}"), u));
            }
            // the multipliers of its rows (M q̈ + Φ_qᵀλ = g)
            for (i, _) in map.rows_of(k).enumerate() {
                c.push(Column::new(
                    format!("{j}.lambda{}", i + 1),
                    "N (position row) or N m (angle row)",
                ));
            }
        }
    }
    if o.drives {
        for d in drives(sys) {
            c.push(Column::new(
                format!("{}.drive", joint_label(sys, d.joint)),
                d.unit,
            ));
        }
    }
    if o.energy {
        for n in ENERGY_COLUMNS {
            c.push(Column::new(n, "J"));
        }
    }
    for s in sensors {
        for (q, u) in s.quantities(sys) {
            c.push(Column::new(format!("{}.{q}", s.name), u));
        }
    }
    c
}

/// The coordinate names of a body's position columns `B.x`, `B.y`, `B.phi`.
pub const POSITION: [&str; 3] = ["x", "y", "phi"];
/// The names of a body's velocity columns `B.vx`, `B.vy`, `B.omega`.
pub const VELOCITY: [&str; 3] = ["vx", "vy", "omega"];
/// The names of a body's acceleration columns `B.ax`, `B.ay`, `B.alpha`.
pub const ACCELERATION: [&str; 3] = ["ax", "ay", "alpha"];

/// The name of every body in column names, in body order: its name when it
/// is a name of the expression grammar (a letter or `_`, then letters,
/// digits, `_`, `.` and `[k]`: `crank`, `arm.link[2]`, `rod.segment[5]`);
/// a builder's numbered name `"segment 5"` as `segment[5]`; any other name,
/// or one two bodies share, as `body<i>` (1-based).
pub fn body_labels(sys: &System) -> Vec<String> {
    let mut labels: Vec<Option<String>> = sys
        .bodies()
        .iter()
        .map(|b| {
            let n = b.name.as_str();
            if is_column_name(n) {
                return Some(n.to_string());
            }
            let (word, k) = n.rsplit_once(' ')?;
            let numbered =
                is_column_name(word) && !k.is_empty() && k.bytes().all(|c| c.is_ascii_digit());
            numbered.then(|| format!("{word}[{k}]"))
        })
        .collect();
    let mut seen = std::collections::HashMap::new();
    for (i, l) in labels.iter().enumerate() {
        if let Some(l) = l {
            seen.entry(l.clone()).or_insert_with(Vec::new).push(i);
        }
    }
    for v in seen.values().filter(|v| v.len() > 1) {
        for &i in v {
            labels[i] = None;
        }
    }
    labels
        .into_iter()
        .enumerate()
        .map(|(i, l)| l.unwrap_or_else(|| format!("body{}", i + 1)))
        .collect()
}

/// Whether `n` is a name of the expression grammar (so a column `n.x` can
/// be read by a metric expression): a letter or `_`, then letters, digits,
/// `_`, `.` and indices `[k]`; not `t`.
pub fn is_column_name(n: &str) -> bool {
    let b = n.as_bytes();
    if n == "t"
        || !b
            .first()
            .is_some_and(|c| c.is_ascii_alphabetic() || *c == b'_')
    {
        return false;
    }
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            c if c.is_ascii_alphanumeric() || c == b'_' || c == b'.' => i += 1,
            b'[' => {
                let d = b[i + 1..].iter().take_while(|c| c.is_ascii_digit()).count();
                if d == 0 || b.get(i + 1 + d) != Some(&b']') {
                    return false;
                }
                i += d + 2;
            }
            _ => return false,
        }
    }
    !n.ends_with('.')
}

/// The column of `names` (a table's header) called `name`: the name
/// itself, or a positional name of earlier versions — `x<i>`, `y<i>`,
/// `phi<i>`, `vx<i>`, `vy<i>`, `omega<i>`, `ax<i>`, `ay<i>`, `alpha<i>`
/// of body `i` (1-based) — read as that body's named column (`x2` →
/// `rod.x` when the second body is `rod`: its `.x` column is the table's
/// `1 + 3(i − 1)`th after `t`).
pub fn find_column(names: &[&str], name: &str) -> Option<usize> {
    if let Some(k) = names.iter().position(|n| *n == name) {
        return Some(k);
    }
    let digits = name.bytes().rev().take_while(u8::is_ascii_digit).count();
    let (coord, i) = name.split_at(name.len() - digits);
    let i: usize = i.parse().ok().filter(|&i| i >= 1)?;
    let known = POSITION.iter().chain(&VELOCITY).chain(&ACCELERATION);
    if !known.clone().any(|c| *c == coord) || names.first() != Some(&"t") {
        return None;
    }
    let body = names.get(1 + 3 * (i - 1))?.strip_suffix(".x")?;
    let full = format!("{body}.{coord}");
    names.iter().position(|n| *n == full)
}

/// The energy columns \[J\], in row order: `kinetic_energy` T,
/// `potential_energy` V = `potential_gravity` + `potential_elastic` (every
/// other potential: springs, contacts, buoyancy), `total_energy` T + V,
/// `work_nonconservative` W = `work_forces` (non-conservative force
/// elements: dampers and friction — negative, the dissipated energy —,
/// actuators, applied loads) + `work_drives` (the constraint forces,
/// `∫λᵀΦ_t`: the drives) since t0, `energy_balance_error` T + V − E0 − W
/// ([`crate::simulation::EnergyTerms`]).
pub const ENERGY_COLUMNS: [&str; 9] = [
    "kinetic_energy",
    "potential_energy",
    "potential_gravity",
    "potential_elastic",
    "total_energy",
    "work_nonconservative",
    "work_forces",
    "work_drives",
    "energy_balance_error",
];

/// The short name of joint `k` in column names (the quoted name in its
/// description, else `joint<k+1>`).
pub fn joint_label(sys: &System, k: usize) -> String {
    joint_short_name(sys.constraints()[k].as_ref()).unwrap_or_else(|| format!("joint{}", k + 1))
}

/// The values of one row in the order of [`columns`], from a [`Sample`];
/// a value that could not be evaluated is NaN.
pub struct RowBuilder<'s> {
    sys: &'s System,
    map: ReactionMap,
    o: OutputQuantities,
    drives: Vec<Drive>,
    sensors: &'s [Sensor],
    row: Vec<f64>,
    values: Vec<f64>,
}

impl<'s> RowBuilder<'s> {
    /// Rows of `sys` with the quantities `o` and `sensors`.
    pub fn new(sys: &'s System, o: OutputQuantities, sensors: &'s [Sensor]) -> Self {
        Self {
            sys,
            map: sys.reaction_map(),
            o,
            drives: if o.drives { drives(sys) } else { Vec::new() },
            sensors,
            row: Vec::new(),
            values: Vec::new(),
        }
    }

    /// The row of `s` (valid until the next call).
    pub fn row(&mut self, s: &Sample<'_>) -> &[f64] {
        let (o, row) = (&self.o, &mut self.row);
        row.clear();
        row.push(s.t);
        // the bodies' coordinates, then each state z = q̇[w]
        let nb = self.sys.n_body_coords();
        row.extend_from_slice(&s.q[..nb]);
        row.extend_from_slice(&s.qd[nb..]);
        row.push(s.constraint_norm);
        if o.velocities {
            row.extend_from_slice(&s.qd[..nb]);
        }
        if o.accelerations {
            match s.qdd {
                Some(a) => row.extend_from_slice(&a[..nb]),
                None => row.extend(std::iter::repeat_n(f64::NAN, nb)),
            }
        }
        if o.reactions {
            for k in 0..self.sys.constraints().len() {
                let r = s
                    .reactions
                    .map_or([f64::NAN; 3], |r| [r[3 * k], r[3 * k + 1], r[3 * k + 2]]);
                // in the frame of the body the reaction acts on: rotate by −φ
                let phi = self.map.body(k).map_or(0.0, |b| s.q[3 * b + 2]);
                let (sn, cs) = phi.sin_cos();
                row.extend([
                    r[0],
                    r[1],
                    r[2],
                    cs * r[0] + sn * r[1],
                    -sn * r[0] + cs * r[1],
                ]);
                for i in self.map.rows_of(k) {
                    row.push(s.lambda.map_or(f64::NAN, |l| l[i]));
                }
            }
        }
        for d in &self.drives {
            row.push(s.lambda.map_or(f64::NAN, |l| d.force(l)));
        }
        if o.energy {
            row.extend(s.energy.map_or([f64::NAN; 9], |e| {
                let v = e.gravity + e.elastic;
                let w = e.work_forces + e.work_drives;
                [
                    e.kinetic,
                    v,
                    e.gravity,
                    e.elastic,
                    e.kinetic + v,
                    w,
                    e.work_forces,
                    e.work_drives,
                    e.balance_error,
                ]
            }));
        }
        evaluate_sensors(self.sensors, self.sys, s.t, s.q, s.qd, &mut self.values);
        row.extend_from_slice(&self.values);
        &self.row
    }
}

/// The file formats of an output table.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// Comma-separated text, a header line of column names, values in
    /// `{:.12e}` (13 significant digits). The default.
    #[default]
    Csv,
    /// Apache Arrow IPC file format (Feather v2): one `Float64` column per
    /// output column with its unit in the field metadata (`"unit"`), rows in
    /// record batches of about 8 MB. Needs the `arrow` feature.
    Arrow,
}

impl Format {
    /// Every format's scenario name, in order.
    pub const NAMES: [&'static str; 2] = ["csv", "arrow"];

    /// The usual file extension (without the dot).
    pub fn extension(self) -> &'static str {
        match self {
            Format::Csv => "csv",
            Format::Arrow => "arrow",
        }
    }

    /// The fewest bytes a value takes in the table, for a lower bound of a
    /// run's file size before it starts: CSV 17 (`{:.12e}` and a comma,
    /// e.g. `1.234567890123e0,`; signs and longer exponents take more),
    /// Arrow 8 (`Float64`; batch headers aside).
    pub fn bytes_per_value(self) -> f64 {
        match self {
            Format::Csv => 17.0,
            Format::Arrow => 8.0,
        }
    }

    /// How often a streaming writer should [`TableWriter::flush`]: every
    /// second for CSV (whole rows on disk); a minute for Arrow, whose
    /// short batches each carry a message header of 16 bytes per column.
    pub fn flush_interval(self) -> std::time::Duration {
        std::time::Duration::from_secs(match self {
            Format::Csv => 1,
            Format::Arrow => 60,
        })
    }

    /// Whether this build can write the format (Arrow needs the `arrow`
    /// feature).
    pub fn available(self) -> bool {
        match self {
            Format::Csv => true,
            Format::Arrow => cfg!(feature = "arrow"),
        }
    }

    /// A writer of this format on `w` with `columns`; an error if this build
    /// lacks the format (see [`Format::available`]) or the header cannot be
    /// written.
    pub fn writer<W: Write + Send + 'static>(
        self,
        w: W,
        columns: &[Column],
    ) -> Result<Box<dyn TableWriter + Send>, TableError> {
        match self {
            Format::Csv => Ok(Box::new(CsvTable::new(w, columns)?)),
            #[cfg(feature = "arrow")]
            Format::Arrow => Ok(Box::new(ArrowTable::new(w, columns)?)),
            #[cfg(not(feature = "arrow"))]
            Format::Arrow => Err(TableError::Unavailable("arrow")),
        }
    }
}

from_words!(Format, "output format", "csv" => Csv, "arrow" => Arrow);

/// Why a table could not be written.
#[derive(Debug, thiserror::Error)]
pub enum TableError {
    /// The underlying writer failed.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// A row with the wrong number of values.
    #[error("row of {got} values for a table of {expected} columns")]
    RowLength {
        /// Number of columns.
        expected: usize,
        /// Values handed over.
        got: usize,
    },
    /// The format is not compiled into this build.
    #[error("output format '{0}' is not available: build mbsolve with the '{0}' feature")]
    Unavailable(&'static str),
    /// The Arrow encoder failed.
    #[error("arrow: {0}")]
    Arrow(String),
    /// A row after [`TableWriter::finish`].
    #[error("the table is already finished")]
    Finished,
}

/// A table written row by row; memory bounded independently of the number
/// of rows.
pub trait TableWriter {
    /// Append one row (one value per column, in column order). NaN marks a
    /// value that could not be evaluated.
    fn write_row(&mut self, row: &[f64]) -> Result<(), TableError>;
    /// Push every complete row written so far to the underlying writer (a
    /// columnar format may write a short batch). Rows stay valid if the
    /// process ends after this returns.
    fn flush(&mut self) -> Result<(), TableError>;
    /// Write what is buffered and the format's trailer; no rows after it.
    fn finish(&mut self) -> Result<(), TableError>;
}

/// CSV rows: a header of column names, then `{:.12e}` values.
pub struct CsvTable<W: Write> {
    w: Option<std::io::BufWriter<W>>,
    ncols: usize,
    line: Vec<u8>,
}

impl<W: Write> CsvTable<W> {
    /// Write the header line of `columns` to `w`.
    pub fn new(w: W, columns: &[Column]) -> Result<Self, TableError> {
        let mut w = std::io::BufWriter::with_capacity(1 << 16, w);
        let names: Vec<std::borrow::Cow<'_, str>> =
            columns.iter().map(|c| csv_field(&c.name)).collect();
        writeln!(w, "{}", names.join(","))?;
        Ok(Self {
            w: Some(w),
            ncols: columns.len(),
            line: Vec::new(),
        })
    }

    /// The underlying writer, once [`TableWriter::finish`] has run.
    pub fn into_inner(mut self) -> Option<W> {
        self.w.take().and_then(|w| w.into_inner().ok())
    }
}

impl<W: Write> TableWriter for CsvTable<W> {
    fn write_row(&mut self, row: &[f64]) -> Result<(), TableError> {
        if row.len() != self.ncols {
            return Err(TableError::RowLength {
                expected: self.ncols,
                got: row.len(),
            });
        }
        let w = self.w.as_mut().ok_or(TableError::Finished)?;
        self.line.clear();
        for (k, v) in row.iter().enumerate() {
            if k > 0 {
                self.line.push(b',');
            }
            push_sci12(&mut self.line, *v);
        }
        self.line.push(b'\n');
        w.write_all(&self.line)?;
        Ok(())
    }

    fn flush(&mut self) -> Result<(), TableError> {
        if let Some(w) = self.w.as_mut() {
            w.flush()?;
        }
        Ok(())
    }

    fn finish(&mut self) -> Result<(), TableError> {
        self.flush()
    }
}

/// A CSV field as RFC 4180 writes it: as is, or — when it holds a comma,
/// a double quote, CR or LF (a joint or sensor named `a,b` or `say "hi"`)
/// — in double quotes with each double quote doubled. Any RFC 4180 reader
/// (the `csv` crate, pandas, `mbsolve plot`) reads the name back whole.
pub fn csv_field(name: &str) -> std::borrow::Cow<'_, str> {
    if name.contains([',', '"', '\r', '\n']) {
        format!("\"{}\"", name.replace('"', "\"\"")).into()
    } else {
        name.into()
    }
}

/// Exact powers of ten representable in `f64` (10^0 … 10^22).
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// Append `v` to `line` with the text of `format!("{v:.12e}")` (13
/// significant digits, correctly rounded), faster than the standard
/// formatter.
///
/// For `1e-10 ≤ |v| < 1e13` the scaled value `|v|·10^k` (`k = 12 − e`,
/// `10^k` exact) is formed without error as `hi + lo` with a fused
/// multiply–add, so rounding it to the 13-digit integer mantissa is exact;
/// an exact tie and every other value go to the standard formatter.
pub fn push_sci12(line: &mut Vec<u8>, v: f64) {
    if !sci12_fast(line, v) {
        use std::io::Write as _;
        let _ = write!(line, "{v:.12e}");
    }
}

/// Two-digit strings "00" … "99".
const DIGIT_PAIRS: &[u8; 200] = b"\
0001020304050607080910111213141516171819\
2021222324252627282930313233343536373839\
4041424344454647484950515253545556575859\
6061626364656667686970717273747576777879\
8081828384858687888990919293949596979899";

/// The rounding error `a·b − hi` of `hi = fl(a·b)`, exactly (Dekker 1971,
/// with Veltkamp's splitting; no overflow in the range used here).
fn two_product_error(a: f64, b: f64, hi: f64) -> f64 {
    let split = |x: f64| {
        let c = 134_217_729.0 * x; // 2^27 + 1
        let h = c - (c - x);
        (h, x - h)
    };
    let (ah, al) = split(a);
    let (bh, bl) = split(b);
    ((ah * bh - hi) + ah * bl + al * bh) + al * bl
}

/// The fast path of [`push_sci12`]; `false` (nothing written) where it
/// does not apply.
fn sci12_fast(line: &mut Vec<u8>, v: f64) -> bool {
    if v == 0.0 {
        line.extend_from_slice(if v.is_sign_negative() {
            b"-0.000000000000e0"
        } else {
            b"0.000000000000e0"
        });
        return true;
    }
    let a = v.abs();
    if !(1e-10..1e13).contains(&a) {
        return false;
    }
    // decimal exponent from the binary one (log10 2 ≈ 78913 / 2^18); it
    // may be one low, which the mantissa's range check below corrects
    let e2 = ((a.to_bits() >> 52) & 0x7ff) as i32 - 1023;
    let mut e = (e2 * 78913) >> 18;
    for _ in 0..3 {
        let k = 12 - e;
        if !(0..=22).contains(&k) {
            return false;
        }
        let p = POW10[k as usize];
        let hi = a * p;
        // a·p = hi + lo exactly (Dekker's product; `mul_add` is a call to
        // libm's fma on the baseline x86-64 target)
        let lo = two_product_error(a, p, hi);
        // hi < 2^53: the integer part converts exactly
        let fl = (hi as u64) as f64;
        // exact: frac and frac − ½ are multiples of ulp(hi) ≥ 2 |lo|, so the
        // rounding decision has the sign of `half`, or else of `lo`
        let half = (hi - fl) - 0.5;
        let up = if half != 0.0 {
            half > 0.0
        } else if lo != 0.0 {
            lo > 0.0
        } else {
            return false; // an exact tie: the standard formatter decides
        };
        let mut m = fl as u64 + up as u64;
        if m < 1_000_000_000_000 {
            e -= 1;
            continue;
        }
        if m > 10_000_000_000_000 || (m == 10_000_000_000_000 && !up) {
            e += 1;
            continue;
        }
        if m == 10_000_000_000_000 {
            // rounded up to the next power of ten
            m = 1_000_000_000_000;
            e += 1;
        }
        // written in place (no copy of a small buffer)
        let start = line.len();
        line.resize(start + 24, 0);
        let buf = &mut line[start..];
        let mut i = 0;
        if v < 0.0 {
            buf[0] = b'-';
            i = 1;
        }
        let lead = m / 1_000_000_000_000;
        let mut rest = m % 1_000_000_000_000;
        buf[i] = b'0' + lead as u8;
        buf[i + 1] = b'.';
        for j in (0..6).rev() {
            let d = (rest % 100) as usize * 2;
            rest /= 100;
            buf[i + 2 + 2 * j] = DIGIT_PAIRS[d];
            buf[i + 3 + 2 * j] = DIGIT_PAIRS[d + 1];
        }
        i += 14;
        buf[i] = b'e';
        i += 1;
        if e < 0 {
            buf[i] = b'-';
            i += 1;
        }
        let ea = e.unsigned_abs();
        if ea >= 10 {
            buf[i] = b'0' + (ea / 10) as u8;
            i += 1;
        }
        buf[i] = b'0' + (ea % 10) as u8;
        i += 1;
        line.truncate(start + i);
        return true;
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cols() -> Vec<Column> {
        vec![Column::new("t", "s"), Column::new("x1", "m")]
    }

    #[test]
    fn csv_rows_and_errors() {
        let mut t = CsvTable::new(Vec::new(), &cols()).unwrap();
        t.write_row(&[0.0, 1.5]).unwrap();
        t.write_row(&[0.25, f64::NAN]).unwrap();
        assert!(matches!(
            t.write_row(&[1.0]),
            Err(TableError::RowLength {
                expected: 2,
                got: 1
            })
        ));
        t.finish().unwrap();
        let text = String::from_utf8(t.into_inner().unwrap()).unwrap();
        assert_eq!(
            text,
            "t,x1\n0.000000000000e0,1.500000000000e0\n2.500000000000e-1,NaN\n"
        );
    }

    /// Names holding commas, double quotes and line breaks are quoted per
    /// RFC 4180 and read back whole, with the row's width, by the `csv`
    /// crate's reader (an independent RFC 4180 implementation).
    #[test]
    fn csv_header_quotes_names_per_rfc_4180() {
        let names = ["t", "a,b.fx", "say \"hi\".fy", "two\nlines.mz", "plain.x"];
        let columns: Vec<Column> = names.iter().map(|n| Column::new(*n, "")).collect();
        let mut t = CsvTable::new(Vec::new(), &columns).unwrap();
        t.write_row(&[0.0, 1.0, 2.0, 3.0, 4.0]).unwrap();
        t.finish().unwrap();
        let text = String::from_utf8(t.into_inner().unwrap()).unwrap();
        assert!(
            text.starts_with("t,\"a,b.fx\",\"say \"\"hi\"\".fy\",\"two\nlines.mz\",plain.x\n"),
            "{text}"
        );
        let mut r = csv::Reader::from_reader(text.as_bytes());
        let header: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
        assert_eq!(header, names);
        let rows: Vec<csv::StringRecord> = r.records().map(Result::unwrap).collect();
        assert_eq!(rows.len(), 1);
        assert_eq!(rows[0].len(), names.len());
        assert_eq!(rows[0][4].parse::<f64>().unwrap(), 4.0);
        assert_eq!(csv_field("plain"), "plain");
    }

    /// `push_sci12` writes the standard formatter's text, on random bit
    /// patterns, on every decade of its fast range, next to powers of ten
    /// and on decimal ties of the 13th digit.
    #[test]
    fn sci12_is_the_standard_text() {
        let check = |v: f64| {
            let mut s = Vec::new();
            push_sci12(&mut s, v);
            assert_eq!(
                String::from_utf8(s).unwrap(),
                format!("{v:.12e}"),
                "bits {:#x}",
                v.to_bits()
            );
        };
        // xorshift: a fixed, reproducible sequence
        let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        for _ in 0..200_000 {
            check(f64::from_bits(next()));
            // uniform in the decades 1e-12 … 1e14, both signs
            let u = (next() >> 11) as f64 / (1u64 << 53) as f64;
            let d = -12.0 + 26.0 * u;
            let s = if next() & 1 == 0 { 1.0 } else { -1.0 };
            check(s * 10f64.powf(d));
        }
        for e in -12..=14 {
            let p = 10f64.powi(e);
            let mut v = p;
            for _ in 0..50 {
                check(v);
                v = f64::from_bits(v.to_bits() - 1);
            }
            let mut v = p;
            for _ in 0..50 {
                check(v);
                v = f64::from_bits(v.to_bits() + 1);
            }
            // decimal ties and their neighbours: d.ddddddddddddd5 × 10^e
            for m in [
                10_000_000_000_005_u64,
                99_999_999_999_995,
                12_345_678_901_235,
            ] {
                let t = m as f64 * 10f64.powi(e - 13);
                for k in -3i64..=3 {
                    check(f64::from_bits((t.to_bits() as i64 + k) as u64));
                }
            }
        }
        for v in [
            0.0,
            -0.0,
            0.5,
            2.5,
            1.0,
            -1.0,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MIN_POSITIVE,
            f64::MAX,
            1e-10,
            1e13,
            5e-324,
        ] {
            check(v);
        }
    }

    #[test]
    fn format_names() {
        for n in Format::NAMES {
            let f: Format = n.parse().unwrap();
            assert_eq!(f.extension(), n);
        }
        let e = "parquet".parse::<Format>().unwrap_err();
        assert!(e.contains("'parquet'") && e.contains("csv or arrow"), "{e}");
    }
}
