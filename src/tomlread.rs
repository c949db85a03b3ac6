//! Typed, located reading of TOML documents (crate-private): every failure carries the file,
//! the line and the key path, so the loaders ([`crate::dh`], [`crate::params`]) can say exactly
//! where a hand-written file is wrong.

use std::ops::Range;

use toml_edit::{ImDocument, Item, TableLike, Value};

use crate::diag::{did_you_mean, line_of, Location, TomlProblem};

/// A failure: where, and what.
pub(crate) type Fail = Box<(Location, TomlProblem)>;

/// The text of one TOML file and the name to report it under.
#[derive(Clone, Copy)]
pub(crate) struct Src<'a> {
    pub file: &'a str,
    pub text: &'a str,
}

impl<'a> Src<'a> {
    pub fn loc(&self, span: Option<Range<usize>>, field: Option<String>) -> Location {
        Location {
            file: self.file.to_string(),
            line: span.map(|s| line_of(self.text, s.start)),
            field,
        }
    }

    pub fn parse(&self) -> Result<ImDocument<&'a str>, Fail> {
        ImDocument::parse(self.text).map_err(|e| {
            let message = e.message().trim().replace('\n', " ");
            Box::new((self.loc(e.span(), None), TomlProblem::Syntax { message }))
        })
    }

    /// The root table of a parsed document.
    pub fn root<'d>(&self, doc: &'d ImDocument<&'a str>) -> TableView<'d>
    where
        'a: 'd,
    {
        TableView {
            src: *self,
            table: doc.as_table(),
            span: None,
            path: String::new(),
        }
    }
}

/// A table (regular or inline) with its location and key path.
pub(crate) struct TableView<'d> {
    src: Src<'d>,
    table: &'d dyn TableLike,
    span: Option<Range<usize>>,
    path: String,
}

fn type_name(item: &Item) -> &'static str {
    match item {
        Item::None => "nothing",
        Item::Table(_) => "a table",
        Item::ArrayOfTables(_) => "an array of tables",
        Item::Value(v) => value_type_name(v),
    }
}

fn value_type_name(v: &Value) -> &'static str {
    match v {
        Value::String(_) => "a string",
        Value::Integer(_) => "an integer",
        Value::Float(_) => "a number",
        Value::Boolean(_) => "a boolean",
        Value::Datetime(_) => "a date/time",
        Value::Array(_) => "an array",
        Value::InlineTable(_) => "an inline table",
    }
}

impl<'d> TableView<'d> {
    /// Key path of `key` inside this table, e.g. `joint[2].alpha`.
    pub fn field(&self, key: &str) -> String {
        if self.path.is_empty() {
            key.to_string()
        } else {
            format!("{}.{key}", self.path)
        }
    }

    /// Location of the table itself (its header line, when it has one).
    pub fn loc(&self) -> Location {
        let field = (!self.path.is_empty()).then(|| self.path.clone());
        self.src.loc(self.span.clone(), field)
    }

    /// Location of `key`'s value (or of the table when the key is absent).
    pub fn loc_of(&self, key: &str) -> Location {
        let span = self
            .table
            .get_key_value(key)
            .and_then(|(k, item)| item.span().or_else(|| k.span()))
            .or_else(|| self.span.clone());
        self.src.loc(span, Some(self.field(key)))
    }

    fn fail(&self, key: &str, problem: TomlProblem) -> Fail {
        Box::new((self.loc_of(key), problem))
    }

    /// Every key must be one of `known` (unknown keys are typos until proven otherwise).
    pub fn check_keys(&self, known: &[&'static str]) -> Result<(), Fail> {
        for (key, _) in self.table.iter() {
            if !known.contains(&key) {
                let span = self.table.key(key).and_then(|k| k.span());
                let problem = TomlProblem::UnknownKey {
                    key: key.to_string(),
                    suggestion: did_you_mean(key, known),
                    expected: known.to_vec(),
                };
                return Err(Box::new((
                    self.src.loc(span, Some(self.field(key))),
                    problem,
                )));
            }
        }
        Ok(())
    }

    fn value(&self, key: &str) -> Option<&'d Value> {
        // Re-borrow through the table's lifetime.
        let table: &'d dyn TableLike = self.table;
        table.get(key).and_then(Item::as_value)
    }

    /// A "missing required key" failure located at this table.
    pub fn missing_key(&self, key: &str) -> Fail {
        Box::new((
            self.loc(),
            TomlProblem::Missing {
                key: key.to_string(),
            },
        ))
    }

    pub fn str_opt(&self, key: &str) -> Result<Option<&'d str>, Fail> {
        let Some(item) = self.table.get(key) else {
            return Ok(None);
        };
        match self.value(key) {
            Some(Value::String(s)) => Ok(Some(s.value().as_str())),
            _ => Err(self.fail(
                key,
                TomlProblem::WrongType {
                    expected: "a string",
                    found: type_name(item),
                },
            )),
        }
    }

    pub fn str_req(&self, key: &str) -> Result<&'d str, Fail> {
        self.str_opt(key)?.ok_or_else(|| self.missing_key(key))
    }

    pub fn bool_opt(&self, key: &str) -> Result<Option<bool>, Fail> {
        let Some(item) = self.table.get(key) else {
            return Ok(None);
        };
        match self.value(key) {
            Some(Value::Boolean(b)) => Ok(Some(*b.value())),
            _ => Err(self.fail(
                key,
                TomlProblem::WrongType {
                    expected: "a boolean",
                    found: type_name(item),
                },
            )),
        }
    }

    pub fn f64_opt(&self, key: &str) -> Result<Option<f64>, Fail> {
        let Some(item) = self.table.get(key) else {
            return Ok(None);
        };
        let x = match self.value(key) {
            Some(v) => number(v),
            None => None,
        };
        match x {
            Some(x) if x.is_finite() => Ok(Some(x)),
            Some(_) => Err(self.fail(key, TomlProblem::NonFinite)),
            None => Err(self.fail(
                key,
                TomlProblem::WrongType {
                    expected: "a number",
                    found: type_name(item),
                },
            )),
        }
    }

    pub fn f64_req(&self, key: &str) -> Result<f64, Fail> {
        self.f64_opt(key)?.ok_or_else(|| self.missing_key(key))
    }

    /// An array of finite numbers, of length `len` when given.
    pub fn f64_array_opt(&self, key: &str, len: Option<usize>) -> Result<Option<Vec<f64>>, Fail> {
        let Some(item) = self.table.get(key) else {
            return Ok(None);
        };
        let Some(Value::Array(arr)) = self.value(key) else {
            return Err(self.fail(
                key,
                TomlProblem::WrongType {
                    expected: "an array of numbers",
                    found: type_name(item),
                },
            ));
        };
        let mut out = Vec::with_capacity(arr.len());
        for (i, v) in arr.iter().enumerate() {
            let elem_loc = || {
                self.src.loc(
                    v.span().or_else(|| item.span()),
                    Some(format!("{}[{}]", self.field(key), i + 1)),
                )
            };
            match number(v) {
                Some(x) if x.is_finite() => out.push(x),
                Some(_) => return Err(Box::new((elem_loc(), TomlProblem::NonFinite))),
                None => {
                    return Err(Box::new((
                        elem_loc(),
                        TomlProblem::WrongType {
                            expected: "a number",
                            found: value_type_name(v),
                        },
                    )))
                }
            }
        }
        if let Some(n) = len {
            if out.len() != n {
                return Err(self.fail(
                    key,
                    TomlProblem::WrongLength {
                        expected: n,
                        found: out.len(),
                    },
                ));
            }
        }
        Ok(Some(out))
    }

    pub fn f64_array_req(&self, key: &str, len: Option<usize>) -> Result<Vec<f64>, Fail> {
        self.f64_array_opt(key, len)?
            .ok_or_else(|| self.missing_key(key))
    }

    /// `[[key]]` tables (or `key = [{...}, ...]`), each with path `key[i]` (1-based).
    pub fn tables(&self, key: &str) -> Result<Vec<TableView<'d>>, Fail> {
        let table: &'d dyn TableLike = self.table;
        let Some(item) = table.get(key) else {
            return Ok(Vec::new());
        };
        let mut out = Vec::new();
        let path = |i: usize| format!("{}[{}]", self.field(key), i + 1);
        match item {
            Item::ArrayOfTables(arr) => {
                for (i, t) in arr.iter().enumerate() {
                    out.push(TableView {
                        src: self.src,
                        table: t,
                        span: t.span(),
                        path: path(i),
                    });
                }
            }
            Item::Value(Value::Array(arr)) => {
                for (i, v) in arr.iter().enumerate() {
                    let Value::InlineTable(t) = v else {
                        return Err(Box::new((
                            self.src.loc(v.span(), Some(path(i))),
                            TomlProblem::WrongType {
                                expected: "a table",
                                found: value_type_name(v),
                            },
                        )));
                    };
                    out.push(TableView {
                        src: self.src,
                        table: t,
                        span: t.span(),
                        path: path(i),
                    });
                }
            }
            other => {
                return Err(self.fail(
                    key,
                    TomlProblem::WrongType {
                        expected: "an array of tables",
                        found: type_name(other),
                    },
                ))
            }
        }
        Ok(out)
    }

    /// A `[key]` sub-table (or inline table).
    pub fn subtable(&self, key: &str) -> Result<Option<TableView<'d>>, Fail> {
        let table: &'d dyn TableLike = self.table;
        let Some(item) = table.get(key) else {
            return Ok(None);
        };
        let span = item.span();
        match item.as_table_like() {
            Some(t) => Ok(Some(TableView {
                src: self.src,
                table: t,
                span,
                path: self.field(key),
            })),
            None => Err(self.fail(
                key,
                TomlProblem::WrongType {
                    expected: "a table",
                    found: type_name(item),
                },
            )),
        }
    }

    /// The keys of this table, in file order.
    pub fn keys(&self) -> Vec<&'d str> {
        let table: &'d dyn TableLike = self.table;
        table.iter().map(|(k, _)| k).collect()
    }
}

fn number(v: &Value) -> Option<f64> {
    match v {
        Value::Float(f) => Some(*f.value()),
        // Integers are exact in f64 up to 2^53; beyond that nobody writes link lengths.
        Value::Integer(i) => Some(*i.value() as f64),
        _ => None,
    }
}
