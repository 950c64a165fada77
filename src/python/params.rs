//! The fit parameters across the Python boundary (`foldmatch_rs.FitParams`): a preset, and
//! settings named as the keys of [`FitParams`]'s serde form, cross as Python values (bool, int,
//! float, str) and are read into the Rust struct by `pythonize`, so every Rust setting is
//! reachable under the name it has in JSON files and in the CLI's `--set KEY=VALUE`, however
//! the struct nests its groups.

use super::to_pyerr;
use crate::error::FoldMatchError;
use crate::fit::FitParams;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat};
use schemars::{schema_for, Schema};
use serde_json::{json, Value};

/// The serde form of `params`: a dict with every key, in the struct's order.
pub(super) fn to_dict<'py>(py: Python<'py>, params: &FitParams) -> PyResult<Bound<'py, PyDict>> {
    let obj = pythonize::pythonize(py, params)
        .map_err(|e| to_pyerr(FoldMatchError::parameter("params", "?", &e.to_string())))?;
    Ok(obj.cast_into::<PyDict>()?)
}

/// The setting names, in the struct's order.
pub(super) fn names(py: Python<'_>) -> PyResult<Vec<String>> {
    to_dict(py, &FitParams::default())?
        .keys()
        .iter()
        .map(|k| k.extract::<String>())
        .collect()
}

/// `base` with the settings of `given` (a dict keyed by setting name) over it, validated: an
/// unknown name, a value of the wrong type or out of range raises `InvalidParameterError`
/// naming the setting (and, for a range, the range).
pub(super) fn over(
    py: Python<'_>,
    base: &FitParams,
    given: Option<&Bound<'_, PyDict>>,
) -> PyResult<FitParams> {
    let Some(given) = given.filter(|g| !g.is_empty()) else {
        base.validate().map_err(to_pyerr)?;
        return Ok(base.clone());
    };
    let known = names(py)?;
    let merged = to_dict(py, base)?;
    for (key, value) in given.iter() {
        let name: String = key.extract().map_err(|_| {
            to_pyerr(FoldMatchError::parameter(
                "params",
                shown(&key),
                "setting names are strings",
            ))
        })?;
        if !known.contains(&name) {
            return Err(to_pyerr(FoldMatchError::parameter(
                &name,
                shown(&value),
                &format!("unknown parameter; known: {}", known.join(", ")),
            )));
        }
        if let Ok(f) = value.cast::<PyFloat>() {
            if !f.value().is_finite() {
                return Err(to_pyerr(FoldMatchError::parameter(
                    &name,
                    shown(&value),
                    "must be a finite number",
                )));
            }
        }
        // pythonize reads a bool setting as the value's truth (so "false" would be true):
        // a bool setting takes a bool only.
        let is_bool = |v: &Bound<'_, PyAny>| v.is_instance_of::<PyBool>();
        if merged.get_item(&name)?.is_some_and(|old| is_bool(&old)) && !is_bool(&value) {
            return Err(to_pyerr(FoldMatchError::parameter(
                &name,
                shown(&value),
                "must be true or false",
            )));
        }
        merged.set_item(&name, &value)?;
    }
    let params: FitParams = match pythonize::depythonize(merged.as_any()) {
        Ok(p) => p,
        Err(whole) => return Err(blame(py, base, given, &whole.to_string())),
    };
    params.validate().map_err(to_pyerr)?;
    Ok(params)
}

/// A full set of settings (every key, as [`to_dict`] writes them) read back: the form in
/// which `FitParams` reaches the fit.
pub(super) fn from_dict(py: Python<'_>, given: &Bound<'_, PyDict>) -> PyResult<FitParams> {
    over(py, &FitParams::default(), Some(given))
}

/// The error of settings that do not read into [`FitParams`]: the first setting whose value
/// alone, over `base`, fails, with serde's reason (`invalid type: string "x", expected f64`).
fn blame(py: Python<'_>, base: &FitParams, given: &Bound<'_, PyDict>, whole: &str) -> PyErr {
    for (key, value) in given.iter() {
        let one = match to_dict(py, base) {
            Ok(d) => d,
            Err(e) => return e,
        };
        if let Err(e) = one.set_item(&key, &value) {
            return e;
        }
        if let Err(e) = pythonize::depythonize::<FitParams>(one.as_any()) {
            let name = key.extract::<String>().unwrap_or_else(|_| shown(&key));
            return to_pyerr(FoldMatchError::parameter(
                &name,
                shown(&value),
                &e.to_string(),
            ));
        }
    }
    to_pyerr(FoldMatchError::parameter("params", "?", whole))
}

/// `repr(value)`, shortened to 60 characters, for an error message.
fn shown(value: &Bound<'_, PyAny>) -> String {
    let text = value
        .repr()
        .map(|r| r.to_string())
        .unwrap_or_else(|_| "?".into());
    match text.char_indices().nth(60) {
        Some((i, _)) => format!("{}…", &text[..i]),
        None => text,
    }
}

/// Every setting of the preset `preset` (`"default"`, `"accurate"`, `"fast"`, `"paper"` or
/// `"tracking"`) with `overrides` over it, checked: a dict keyed by setting name. Raises
/// `InvalidParameterError` naming an unknown preset or setting, or a value of the wrong type
/// or out of its range.
#[pyfunction]
#[pyo3(signature = (preset="default", overrides=None))]
pub(super) fn fit_params<'py>(
    py: Python<'py>,
    preset: &str,
    overrides: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let base = FitParams::preset(preset).map_err(to_pyerr)?;
    let params = over(py, &base, overrides)?;
    to_dict(py, &params)
}

/// The names of every setting of `FitParams` (the keys of its JSON form), in the struct's
/// order.
#[pyfunction]
pub(super) fn param_names(py: Python<'_>) -> PyResult<Vec<String>> {
    names(py)
}

/// The groups of settings, as [`FitParams`] nests them: each nested struct's title and JSON
/// schema (its doc comment and its fields'), in order; the settings of the top level come
/// last, under [`TOP_GROUP`].
fn group_schemas() -> Vec<(&'static str, Schema)> {
    use crate::fit::{Acceleration, ModelConstants, Readings, Schedule};
    vec![
        ("Model constants", schema_for!(ModelConstants)),
        ("Paper readings", schema_for!(Readings)),
        ("Schedule", schema_for!(Schedule)),
        ("Acceleration", schema_for!(Acceleration)),
    ]
}

/// The title and doc of the settings at the top level of [`FitParams`].
const TOP_GROUP: (&str, &str) = (
    "The run",
    "The method, the number of iterations and the run's controls (early stop, placement, \
     snapshots).",
);

/// The reference of every setting, grouped as [`FitParams`] nests them: a list of groups
/// `{"title", "doc", "settings": [{"name", "type", "default", "doc", "choices"}]}`, read from
/// the struct's JSON schema (`schemars`), so from its own doc comments. `type` is `"int"`,
/// `"float"`, `"bool"` or `"str"`; `choices` lists a `str` setting's values as `[value, doc]`.
#[pyfunction]
pub(super) fn param_reference(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    let root = schema_for!(FitParams);
    let defs = root.get("$defs").cloned().unwrap_or(Value::Null);
    let properties = root
        .get("properties")
        .and_then(Value::as_object)
        .cloned()
        .unwrap_or_default();
    // The schema's map is sorted by name; the reference keeps the struct's (serde's) order.
    let order = names(py)?;
    let mut groups: Vec<Value> = Vec::new();
    let mut placed: Vec<String> = Vec::new();
    let mut top = root.as_object().cloned().unwrap_or_default();
    top.insert("description".into(), json!(TOP_GROUP.1));
    let nested: Vec<_> = group_schemas()
        .into_iter()
        .map(|(title, s)| (title, s.as_object().cloned().unwrap_or_default()))
        .collect();
    // The nested groups claim their settings first; the top level's are the rest, shown first.
    for (title, group) in nested.iter().chain(std::iter::once(&(TOP_GROUP.0, top))) {
        let names: Vec<String> = match group.get("properties").and_then(Value::as_object) {
            Some(own) => own
                .keys()
                .filter(|k| !placed.contains(k))
                .cloned()
                .collect(),
            None => Vec::new(),
        };
        let settings: Vec<Value> = order
            .iter()
            .filter(|k| names.contains(k))
            .filter_map(|name| Some(setting(name, properties.get(name)?, &defs)))
            .collect();
        placed.extend(names);
        let text = |key: &str| {
            group
                .get(key)
                .and_then(Value::as_str)
                .unwrap_or("")
                .to_string()
        };
        let entry = json!({
            "title": title,
            "doc": text("description"),
            "settings": settings,
        });
        if title == &TOP_GROUP.0 {
            groups.insert(0, entry);
        } else {
            groups.push(entry);
        }
    }
    pythonize::pythonize(py, &groups)
        .map_err(|e| super::InternalError::new_err(format!("parameter reference: {e}")))
}

/// One setting's reference entry (see [`param_reference`]).
fn setting(name: &str, schema: &Value, defs: &Value) -> Value {
    let target = match schema.get("$ref").and_then(Value::as_str) {
        Some(r) => defs
            .get(r.trim_start_matches("#/$defs/"))
            .cloned()
            .unwrap_or(Value::Null),
        None => schema.clone(),
    };
    let kind = match target.get("type").and_then(Value::as_str) {
        Some("integer") => "int",
        Some("number") => "float",
        Some("boolean") => "bool",
        _ => "str",
    };
    let mut choices: Vec<Value> = Vec::new();
    if let Some(variants) = target.get("oneOf").and_then(Value::as_array) {
        for v in variants {
            let value = v
                .get("const")
                .or_else(|| v.get("enum").and_then(|e| e.get(0)));
            if let Some(value) = value {
                let doc = v.get("description").cloned().unwrap_or(json!(""));
                choices.push(json!([value, doc]));
            }
        }
    } else if let Some(values) = target.get("enum").and_then(Value::as_array) {
        choices.extend(values.iter().map(|v| json!([v, ""])));
    }
    let doc = schema
        .get("description")
        .or_else(|| target.get("description"))
        .and_then(Value::as_str)
        .unwrap_or("");
    json!({
        "name": name,
        "type": kind,
        "default": schema.get("default").cloned().unwrap_or(Value::Null),
        "doc": doc,
        "choices": choices,
    })
}
