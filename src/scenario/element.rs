//! The two-step read of a tagged scenario table (`[[force]]`, `[[joint]]`,
//! `[[sensor]]`): its `type` first, then the type's own serde struct
//! (`deny_unknown_fields`) from the same table. Each type's keys are the
//! fields of its struct, so a typo lists this type's keys and suggests the
//! nearest, and errors keep their key path (`force[2].damping`).

use super::model::{body_index, body_point, body_ref, RawPoint};
use super::{error, ScenarioError};
use crate::model::{BodyPoint, BodyRef, SystemBuilder};
use serde::de::{self, DeserializeOwned, Visitor};
use serde::Deserialize;
use std::collections::HashMap;

/// One tagged table as written: its keys and values, read by type later.
#[derive(Debug, Clone, Deserialize)]
#[serde(transparent)]
pub(super) struct RawTagged(pub(super) toml::Table);

impl RawTagged {
    /// The optional `name` key (a string), for element names and messages.
    pub(super) fn name(&self) -> Option<&str> {
        self.0.get("name").and_then(toml::Value::as_str)
    }
}

/// A `[[force]]` or `[[joint]]` type: its serde struct (the keys besides
/// `type` and `name`, `deny_unknown_fields`) and what it adds to the model
/// being built in the context `C` (force elements, a constraint).
pub(super) trait ElementType<C>: DeserializeOwned {
    /// The `type` value that selects it.
    const TYPE: &'static str;
    /// Adds what the table declares; errors name `<table>[k].<key>`.
    fn add(self, cx: &mut C) -> Result<(), ScenarioError>;
}

/// What a kind of element builds with besides its [`Site`] and the
/// system builder: `()` for `[[joint]]`s, gravity, the joints and the
/// states for `[[force]]`s.
pub(super) trait Knows {
    /// The data, borrowed for `'a`.
    type Data<'a>;
}

impl Knows for () {
    type Data<'a> = ();
}

/// What an element type of the kind `K` builds with: where its table is,
/// its name and the model's names (its key, error and body helpers,
/// through `Deref`), the system being built, and what its kind knows.
pub(super) struct Context<'a, K: Knows> {
    /// Where the table is.
    pub(super) site: Site<'a>,
    /// The system being built.
    pub(super) builder: &'a mut SystemBuilder,
    /// What the kind knows besides.
    pub(super) known: K::Data<'a>,
}

impl<'a, K: Knows> std::ops::Deref for Context<'a, K> {
    type Target = Site<'a>;
    fn deref(&self) -> &Site<'a> {
        &self.site
    }
}

/// A type's `add` in the context of its kind `K`: reads the table as the
/// type and adds what it declares.
pub(super) type AddFn<K> = for<'a> fn(&RawTagged, &mut Context<'a, K>) -> Result<(), ScenarioError>;

impl<K: Knows> Decl<AddFn<K>> {
    /// The row of the type `T` of the kind `K`.
    pub(super) const fn of<T: for<'a> ElementType<Context<'a, K>>>() -> Self {
        Decl::new::<T>(T::TYPE, |raw, cx| {
            let site = &cx.site;
            site.kind
                .read::<T>(raw, T::TYPE, site.k, site.file)?
                .add(cx)
        })
    }
}

/// A type's row in the list of the `[[force]]`, `[[joint]]` or
/// `[[sensor]]` types: its `type` value, its keys and `add`, which reads a
/// table as the type and adds it (`A`: the function type of its kind;
/// `()` where a kind reads its types itself).
pub(super) struct Decl<A> {
    /// The `type` value.
    pub(super) name: &'static str,
    /// Its keys besides `type` and `name`, in declaration order (read by
    /// the test that holds docs/scenarios.md to the declarations).
    #[cfg_attr(not(test), allow(dead_code))]
    pub(super) keys: fn() -> &'static [&'static str],
    /// Reads a table as this type and adds what it declares.
    pub(super) add: A,
}

impl<A> Decl<A> {
    /// The row of the type `name` whose struct is `T`.
    pub(super) const fn new<T: DeserializeOwned>(name: &'static str, add: A) -> Self {
        Decl {
            name,
            keys: keys_of::<T>,
            add,
        }
    }
}

/// A kind of tagged table: its name in key paths (`force`) and in
/// messages (`force element`).
pub(super) struct Kind {
    /// The table's name in key paths.
    pub(super) table: &'static str,
    /// What one table declares, in messages.
    pub(super) what: &'static str,
}

impl Kind {
    /// The kind of the `table` tables, each declaring `what`.
    pub(super) const fn new(table: &'static str, what: &'static str) -> Self {
        Kind { table, what }
    }

    /// `<table>[k]`.
    pub(super) fn path(&self, k: usize) -> String {
        format!("{}[{k}]", self.table)
    }

    /// [`read`]: table `k` of this kind as the struct `T` of the type
    /// `name`.
    pub(super) fn read<T: DeserializeOwned>(
        &self,
        raw: &RawTagged,
        name: &str,
        k: usize,
        file: &str,
    ) -> Result<T, ScenarioError> {
        read(raw, &self.path(k), &format!("{name} {}", self.what), file)
    }

    /// Where table `k` (`raw`) is, with the model's names.
    pub(super) fn site<'a>(
        &'static self,
        raw: &RawTagged,
        k: usize,
        names: &'a HashMap<String, usize>,
        ends: &'a HashMap<usize, f64>,
        file: &'a str,
    ) -> Site<'a> {
        Site {
            kind: self,
            k,
            names,
            ends,
            file,
            name: raw
                .name()
                .map_or_else(|| format!("{}{}", self.table, k + 1), str::to_string),
        }
    }

    /// The row of `types` that the `type` of table `k` names ([`tag`]),
    /// after checking its optional `name` ([`check_name`]).
    pub(super) fn decl<'t, A>(
        &self,
        raw: &RawTagged,
        types: &'t [Decl<A>],
        k: usize,
        file: &str,
    ) -> Result<&'t Decl<A>, ScenarioError> {
        let path = self.path(k);
        let kind = tag(raw, &path, self.table, types.iter().map(|t| t.name), file)?;
        check_name(raw, &path, file)?;
        Ok(types.iter().find(|t| t.name == kind).expect("tag checked"))
    }
}

/// Where an element's table is (`force[k]`, `joint[k]`, `sensor[k]`) and
/// the model's names its keys resolve against: the key paths, errors,
/// bodies and points every `[[force]]`, `[[joint]]` and `[[sensor]]` type
/// reads its table with.
pub(super) struct Site<'a> {
    /// The kind of table.
    pub(super) kind: &'static Kind,
    /// The index k of the table.
    pub(super) k: usize,
    /// Body index by name.
    pub(super) names: &'a HashMap<String, usize>,
    /// The half length of every rod segment and chain link by body index.
    pub(super) ends: &'a HashMap<usize, f64>,
    /// The scenario file, for errors.
    pub(super) file: &'a str,
    /// The element's name: its `name`, default `<table>{k+1}`.
    pub(super) name: String,
}

impl Site<'_> {
    /// `<table>[k].<fld>`.
    pub(super) fn key(&self, fld: &str) -> String {
        format!("{}.{fld}", self.kind.path(self.k))
    }

    /// An error at `<table>[k].<fld>`.
    pub(super) fn err(&self, fld: &str, message: impl Into<String>) -> ScenarioError {
        error(self.file, self.key(fld), message)
    }

    /// The body (or ground) named at `fld`.
    pub(super) fn body_ref(&self, fld: &str, name: &str) -> Result<BodyRef, ScenarioError> {
        body_ref(self.names, self.file, self.key(fld), name)
    }

    /// The body (not the ground) named at `fld`.
    pub(super) fn body_index(&self, fld: &str, name: &str) -> Result<usize, ScenarioError> {
        body_index(self.names, self.file, self.key(fld), name)
    }

    /// `body_i` and `body_j` of a two-body element (`what`, e.g. "a
    /// spring"), which must differ.
    pub(super) fn two_bodies(
        &self,
        what: &str,
        body_i: &str,
        body_j: &str,
    ) -> Result<(BodyRef, BodyRef), ScenarioError> {
        let bi = self.body_ref("body_i", body_i)?;
        let bj = self.body_ref("body_j", body_j)?;
        if bi == bj {
            return Err(self.err(
                "body_j",
                format!("{what} must connect two different bodies, got '{body_j}' twice"),
            ));
        }
        Ok((bi, bj))
    }

    /// The two ends of a two-body element (`what`, e.g. "a spring"):
    /// `body_i` and `body_j`, which must differ ([`Site::two_bodies`]),
    /// with their points `point_i` and `point_j` ([`Site::point`]).
    pub(super) fn two_points(
        &self,
        what: &str,
        (body_i, point_i): (&str, Option<RawPoint>),
        (body_j, point_j): (&str, Option<RawPoint>),
    ) -> Result<(BodyPoint, BodyPoint), ScenarioError> {
        let (bi, bj) = self.two_bodies(what, body_i, body_j)?;
        Ok((
            BodyPoint::new(bi, self.point("point_i", point_i, bi)?),
            BodyPoint::new(bj, self.point("point_j", point_j, bj)?),
        ))
    }

    /// The body-frame point at `fld` on `body` (`None`: the origin).
    pub(super) fn point(
        &self,
        fld: &str,
        p: Option<RawPoint>,
        body: BodyRef,
    ) -> Result<[f64; 2], ScenarioError> {
        body_point(p, body, self.ends, self.file, self.key(fld))
    }
}

/// Checks that the optional `name` of the table at `path` is a string.
pub(super) fn check_name(raw: &RawTagged, path: &str, file: &str) -> Result<(), ScenarioError> {
    match raw.0.get("name") {
        Some(v) if !v.is_str() => Err(error(
            file,
            format!("{path}.name"),
            format!("invalid type: {} `{v}`, expected a string", v.type_str()),
        )),
        _ => Ok(()),
    }
}

/// The `type` of the table at `path` (e.g. `force[2]`), checked against
/// `types`; `what` names the table in messages (`force`, `joint`, `sensor`).
pub(super) fn tag<'a>(
    raw: &RawTagged,
    path: &str,
    what: &str,
    types: impl Iterator<Item = &'a str> + Clone,
    file: &str,
) -> Result<&'a str, ScenarioError> {
    let key = format!("{path}.type");
    let kind = match raw.0.get("type") {
        Some(toml::Value::String(s)) => s.as_str(),
        Some(v) => {
            return Err(error(
                file,
                key,
                format!("invalid type: {} `{v}`, expected a string", v.type_str()),
            ))
        }
        None => return Err(error(file, key, format!("missing: a {what} needs a type"))),
    };
    types.clone().find(|t| *t == kind).ok_or_else(|| {
        let all: Vec<&str> = types.collect();
        let hint = nearest(kind, &all)
            .map(|n| format!("; did you mean '{n}'?"))
            .unwrap_or_default();
        error(
            file,
            key,
            format!(
                "unknown {what} type '{kind}' (expected one of {}){hint}",
                all.join(", ")
            ),
        )
    })
}

/// Reads the table at `path` (without its `type`) as the struct `T` of
/// one type; `what` names the type in messages (`spring force element`).
/// An unknown key is reported at its own path with this type's keys and
/// the nearest one; a missing key at its own path.
pub(super) fn read<T: DeserializeOwned>(
    raw: &RawTagged,
    path: &str,
    what: &str,
    file: &str,
) -> Result<T, ScenarioError> {
    let mut table = raw.0.clone();
    table.remove("type");
    table.remove("name");
    serde_path_to_error::deserialize(toml::Value::Table(table)).map_err(
        |e: serde_path_to_error::Error<toml::de::Error>| {
            let inner = e.inner().message().to_string();
            let sub = e.path().to_string();
            let at = |k: &str| {
                if k.is_empty() || k == "." {
                    path.to_string()
                } else {
                    format!("{path}.{k}")
                }
            };
            let keys = keys_of::<T>();
            if let Some(field) = quoted(&inner, "unknown field `") {
                let hint = nearest(field, keys)
                    .map(|n| format!("; did you mean `{n}`?"))
                    .unwrap_or_default();
                let key = if sub.ends_with(field) {
                    at(&sub)
                } else {
                    at(field)
                };
                return error(
                    file,
                    key,
                    format!(
                        "not a key of {} {what} (its keys: type, name, {}){hint}",
                        article(what),
                        keys.join(", ")
                    ),
                );
            }
            if let Some(field) = quoted(&inner, "missing field `") {
                return error(
                    file,
                    at(field),
                    format!("missing: {} {what} needs {field}", article(what)),
                );
            }
            error(file, at(&sub), inner)
        },
    )
}

/// "an" before a vowel, else "a".
fn article(word: &str) -> &'static str {
    if word.starts_with(['a', 'e', 'i', 'o', 'u']) {
        "an"
    } else {
        "a"
    }
}

/// The text between `prefix` and the next backtick of `message`.
fn quoted<'m>(message: &'m str, prefix: &str) -> Option<&'m str> {
    let rest = message.strip_prefix(prefix)?;
    rest.split_once('`').map(|(f, _)| f)
}

/// The keys of the serde struct `T` (its field names, in declaration
/// order), read from its `Deserialize` implementation.
pub(super) fn keys_of<'de, T: Deserialize<'de>>() -> &'static [&'static str] {
    /// A deserializer that only records the fields a struct asks for.
    struct Probe;
    #[derive(Debug)]
    struct Fields(&'static [&'static str]);
    impl std::fmt::Display for Fields {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("fields probed")
        }
    }
    impl std::error::Error for Fields {}
    impl de::Error for Fields {
        fn custom<M: std::fmt::Display>(_: M) -> Self {
            Fields(&[])
        }
    }
    impl<'de> de::Deserializer<'de> for Probe {
        type Error = Fields;
        fn deserialize_any<V: Visitor<'de>>(self, _: V) -> Result<V::Value, Fields> {
            Err(Fields(&[]))
        }
        fn deserialize_struct<V: Visitor<'de>>(
            self,
            _: &'static str,
            fields: &'static [&'static str],
            _: V,
        ) -> Result<V::Value, Fields> {
            Err(Fields(fields))
        }
        serde::forward_to_deserialize_any! {
            bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string
            bytes byte_buf option unit unit_struct newtype_struct seq tuple
            tuple_struct map enum identifier ignored_any
        }
    }
    match T::deserialize(Probe) {
        Err(Fields(f)) => f,
        Ok(_) => &[],
    }
}

/// The candidate nearest to `word` by edit distance, if it is close
/// enough to be a likely typo (2 edits, 3 for words of 9 characters or
/// more).
pub(super) fn nearest<'a>(word: &str, candidates: &[&'a str]) -> Option<&'a str> {
    let limit = (word.chars().count() / 3).clamp(2, 3);
    candidates
        .iter()
        .map(|c| (levenshtein(word, c), *c))
        .filter(|(d, _)| *d <= limit)
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c)
}

/// The Levenshtein distance (insertions, deletions, substitutions) of
/// `a` and `b`, in characters.
fn levenshtein(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diag = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let next = (diag + usize::from(ca != *cb))
                .min(row[j] + 1)
                .min(row[j + 1] + 1);
            diag = row[j + 1];
            row[j + 1] = next;
        }
    }
    row[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Sample {
        #[allow(dead_code)]
        body: String,
        #[allow(dead_code)]
        damping: Option<f64>,
    }

    fn raw(text: &str) -> RawTagged {
        RawTagged(text.parse().unwrap())
    }

    #[test]
    fn keys_come_from_the_struct() {
        assert_eq!(keys_of::<Sample>(), &["body", "damping"]);
    }

    #[test]
    fn edit_distance_and_nearest() {
        assert_eq!(levenshtein("dampin", "damping"), 1);
        assert_eq!(levenshtein("kitten", "sitting"), 3);
        assert_eq!(levenshtein("", "abc"), 3);
        assert_eq!(nearest("dampin", &["body", "damping"]), Some("damping"));
        assert_eq!(nearest("xyz", &["body", "damping"]), None);
    }

    #[test]
    fn a_typo_is_reported_at_its_path_with_the_nearest_key() {
        let e = read::<Sample>(
            &raw("type = \"s\"\nbody = \"a\"\ndampin = 1.0"),
            "force[2]",
            "s force element",
            "f.toml",
        )
        .unwrap_err();
        assert_eq!(e.key, "force[2].dampin", "{e}");
        assert!(e.message.contains("did you mean `damping`?"), "{e}");
        assert!(e.message.contains("type, name, body, damping"), "{e}");
        let e = read::<Sample>(&raw("damping = 1.0"), "force[0]", "s", "f.toml").unwrap_err();
        assert_eq!(e.key, "force[0].body", "{e}");
        assert!(e.message.contains("missing"), "{e}");
        let e = read::<Sample>(&raw("body = 3"), "force[0]", "s", "f.toml").unwrap_err();
        assert_eq!(e.key, "force[0].body", "{e}");
        assert!(e.message.contains("invalid type"), "{e}");
    }
}

/// The keys docs/scenarios.md lists for each type of a tagged table, for
/// the tests that hold the declarations and the reference together.
#[cfg(test)]
pub(super) mod docs {
    /// The reference of every scenario key.
    pub(in crate::scenario) const SCENARIOS_MD: &str = include_str!("../../docs/scenarios.md");

    /// The identifiers in backticks in `cell` (`"x"`, `[0, 0]` are not).
    fn identifiers(cell: &str) -> Vec<String> {
        cell.split('`')
            .skip(1)
            .step_by(2)
            .filter(|w| !w.is_empty() && w.chars().all(|c| c.is_ascii_lowercase() || c == '_'))
            .map(str::to_string)
            .collect()
    }

    /// The rows of the first table after the line starting with `heading`:
    /// its header cells and each row's cells.
    pub(in crate::scenario) fn table(heading: &str) -> (Vec<String>, Vec<Vec<String>>) {
        let mut lines = SCENARIOS_MD
            .lines()
            .skip_while(|l| !l.starts_with(heading))
            .skip(1)
            .skip_while(|l| !l.starts_with('|'));
        let cells = |l: &str| -> Vec<String> {
            l.trim()
                .trim_matches('|')
                .split(" | ")
                .map(|c| c.trim().to_string())
                .collect()
        };
        let header = cells(
            lines
                .next()
                .unwrap_or_else(|| panic!("no table after {heading}")),
        );
        let rows = lines
            .skip(1)
            .take_while(|l| l.starts_with('|'))
            .map(cells)
            .collect();
        (header, rows)
    }

    /// The keys of the `| key | …` table (first column) or of the
    /// `| term | keys | …` table (second column) after `heading`, sorted.
    pub(in crate::scenario) fn keys_after(heading: &str) -> Vec<String> {
        let (header, rows) = table(heading);
        let col = usize::from(header[0] != "key");
        let mut keys: Vec<String> = rows.iter().flat_map(|r| identifiers(&r[col])).collect();
        keys.sort();
        keys.dedup();
        keys
    }

    /// The keys of the row of `type` in the `| type | keys | …` table
    /// after `heading` (up to a colon), sorted.
    pub(in crate::scenario) fn keys_of_row(heading: &str, kind: &str) -> Vec<String> {
        let (_, rows) = table(heading);
        let row = rows
            .iter()
            .find(|r| r[0] == format!("`{kind}`"))
            .unwrap_or_else(|| panic!("docs/scenarios.md: no row `{kind}` after {heading}"));
        // a key's description after a colon ("`force`: the `name` of …")
        // names no keys
        let cell = row[1].split(": ").next().unwrap_or_default();
        let mut keys = identifiers(cell);
        keys.sort();
        keys.dedup();
        keys
    }

    /// docs/scenarios.md lists exactly each row's keys of `types`, as
    /// `listed(type)` finds them; `table` names the table in messages.
    pub(in crate::scenario) fn check_keys<A>(
        types: &[super::Decl<A>],
        table: &str,
        listed: impl Fn(&str) -> Vec<String>,
    ) {
        for t in types {
            assert_eq!(
                listed(t.name),
                sorted((t.keys)()),
                "docs/scenarios.md, {table} type {}: the keys differ from its struct",
                t.name
            );
        }
    }

    /// `table` appended to `base` fails at `<kind>[0].<key>` as not a key
    /// of its type, suggesting `near`; the error, for further checks.
    pub(in crate::scenario) fn check_typo(
        kind: &super::Kind,
        base: &str,
        (table, key, near): (&str, &str, &str),
    ) -> crate::scenario::ScenarioError {
        let e =
            crate::scenario::parse(&format!("{base}{table}"), "f.toml", "f", &[]).expect_err(table);
        assert_eq!(e.key, format!("{}[0].{key}", kind.table), "{e}");
        assert!(
            e.message.contains(&format!("did you mean `{near}`?")),
            "{e}"
        );
        let ty = table.split('"').nth(1).unwrap();
        let what = format!("{ty} {}", kind.what);
        let not_a_key = format!("not a key of {} {what}", super::article(&what));
        assert!(e.message.starts_with(&not_a_key), "{e}");
        e
    }

    /// `keys` sorted, as owned strings.
    pub(in crate::scenario) fn sorted(keys: &[&str]) -> Vec<String> {
        let mut k: Vec<String> = keys.iter().map(|s| s.to_string()).collect();
        k.sort();
        k
    }
}

/// The `[[force]]`, `[[joint]]` and `[[sensor]]` declarations held to
/// docs/scenarios.md and to their typo messages, every kind alike.
#[cfg(test)]
mod kinds {
    use super::docs::{check_keys, check_typo, keys_after, keys_of_row};
    use super::{Decl, Kind};
    use crate::scenario::forces::{self, FORCE};
    use crate::scenario::joints::{self, JOINT};
    use crate::scenario::sensor::{self, SENSOR};

    /// docs/scenarios.md lists exactly each type's keys, as its struct
    /// declares them.
    #[test]
    fn docs_list_each_types_keys() {
        check_keys(forces::TYPES, "[[force]]", |t| {
            keys_after(&format!("### `{t}` —"))
        });
        check_keys(joints::TYPES, "[[joint]]", |t| {
            keys_of_row("## `[[joint]]`", t)
        });
        check_keys(sensor::TYPES, "[[sensor]]", |t| {
            keys_of_row("## `[[sensor]]`", t)
        });
    }

    /// A scenario of one body `a` up to an open table of `kind` (a sensor
    /// named `m`, with a spring `s` to read).
    fn base(kind: &Kind) -> String {
        let body = "[[body]]\nname = \"a\"\nmass = 1.0\ninertia = 1.0\n[time]\nend = 0.1\n";
        match kind.table {
            "sensor" => format!(
                "{body}[[force]]\nname = \"s\"\ntype = \"spring\"\nbody_i = \"a\"\n\
                 body_j = \"ground\"\n[[sensor]]\nname = \"m\"\n"
            ),
            table => format!("{body}[[{table}]]\n"),
        }
    }

    /// The keys of type `ty` of `kind`.
    fn keys(kind: &Kind, ty: &str) -> &'static [&'static str] {
        fn of<A>(types: &[Decl<A>], ty: &str) -> &'static [&'static str] {
            (types.iter().find(|t| t.name == ty).expect("a type").keys)()
        }
        match kind.table {
            "force" => of(forces::TYPES, ty),
            "joint" => of(joints::TYPES, ty),
            _ => of(sensor::TYPES, ty),
        }
    }

    /// A typo in a table is reported at its key with the nearest key of
    /// its type, and the message lists this type's keys (a force's not
    /// those of every force type).
    #[test]
    fn typos_suggest_the_nearest_key_of_this_type() {
        let cases = [
            (&FORCE, "type = \"torque\"\nbody = \"a\"\ntorqe = 1.0", "torqe", "torque"),
            (&FORCE, "type = \"force\"\nbody = \"a\"\nfx = 1.0\nfy = 0.0\npoimt = [0.0, 0.0]", "poimt", "point"),
            (&FORCE, "type = \"spring\"\nbody_i = \"a\"\nbody_j = \"ground\"\ndampin = 1.0", "dampin", "damping"),
            (&FORCE, "type = \"rotational_spring\"\nbody_i = \"a\"\nbody_j = \"ground\"\nrest_angel = 1.0", "rest_angel", "rest_angle"),
            (&FORCE, "type = \"contact\"\nbody = \"a\"\nstiffness = 1.0\nwall_normal_dg = 90.0", "wall_normal_dg", "wall_normal_deg"),
            (&FORCE, "type = \"fluid\"\nbody = \"a\"\nfluid_density = 1.0\nvolum = 1.0", "volum", "volume"),
            (&FORCE, "type = \"expression\"\nbody = \"a\"\ntorq = \"1\"", "torq", "torque"),
            (&JOINT, "type = \"revolute\"\nbody_i = \"a\"\nbody_j = \"ground\"\npoint_i = [0.0, 0.0]\npoint_jj = [0.0, 0.0]", "point_jj", "point_j"),
            (&JOINT, "type = \"translational\"\nbody_i = \"a\"\nbody_j = \"ground\"\naxis = [1.0, 0.0]", "axis", "axis_i"),
            (&JOINT, "type = \"drive_coordinate\"\nbody = \"a\"\ncoordinate = \"x\"\nmotoin = 0.0", "motoin", "motion"),
            (&JOINT, "type = \"drive_angle\"\nbody_i = \"a\"\nbody_jj = \"ground\"\nmotion = 0.0", "body_jj", "body_j"),
            (&SENSOR, "type = \"point\"\nbody = \"a\"\npiont = [0.0, 0.0]", "piont", "point"),
            (&SENSOR, "type = \"joint_angle\"\njiont = \"j\"", "jiont", "joint"),
            (&SENSOR, "type = \"distance\"\nbody_i = \"a\"\nbody_j = \"ground\"\npoint_ii = [0.0, 0.0]", "point_ii", "point_i"),
            (&SENSOR, "type = \"force_element\"\nforces = \"s\"", "forces", "force"),
            (&SENSOR, "type = \"contact\"\nforc = \"s\"", "forc", "force"),
        ];
        for (kind, table, key, near) in cases {
            let e = check_typo(kind, &base(kind), (table, key, near));
            let ty = table.split('"').nth(1).unwrap();
            assert!(e.message.contains(&keys(kind, ty).join(", ")), "{e}");
            if ty != "fluid" {
                assert!(!e.message.contains("fluid_density"), "{e}");
            }
        }
    }

    /// A key of another type of the kind is reported with this type's
    /// keys and no suggestion; a misspelt type with the nearest type.
    #[test]
    fn other_types_keys_and_misspelt_types_are_reported_at_their_key() {
        let cases = [
            (
                &FORCE,
                "type = \"spring\"\nbody_i = \"a\"\nbody_j = \"ground\"\nradius = 0.1",
                "radius",
                "not a key of a spring force element",
            ),
            (
                &JOINT,
                "type = \"revolut\"\nbody_i = \"a\"\nbody_j = \"ground\"",
                "type",
                "did you mean 'revolute'?",
            ),
        ];
        for (kind, table, key, says) in cases {
            let e = crate::scenario::parse(&format!("{}{table}", base(kind)), "f.toml", "f", &[])
                .unwrap_err();
            assert_eq!(e.key, format!("{}[0].{key}", kind.table), "{e}");
            assert!(e.message.contains(says), "{e}");
            assert_eq!(e.message.contains("did you mean"), key == "type", "{e}");
        }
    }
}
