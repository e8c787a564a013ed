//! `gfcs._core.FabricConfig`: every gain of the fabric (GF Sec. VII-A components, App. E-B speed control)
//! with its documented default. Built from a TOML/YAML/JSON file, a text, or a (nested) dict; unknown fields
//! and values of the wrong kind raise `FormatError` naming the file and the dotted field path.

use fabric_core::fabric::FabricConfig;
use fabric_core::FabricError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use serde_json::{Map, Number, Value};

use crate::errors::{error, guarded};
use crate::robot::path_arg;

/// A Python value (dict, list, bool, int, float, str, None, numpy scalar) as JSON; `what` is its dotted path.
pub(crate) fn to_json(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Value> {
    let bad = |message: String| {
        error(FabricError::Format {
            file: "<dict>".into(),
            field: what.into(),
            message,
        })
    };
    if obj.is_none() {
        return Ok(Value::Null);
    }
    if let Ok(d) = obj.cast::<PyDict>() {
        let mut map = Map::new();
        for (k, v) in d.iter() {
            let key: String = k
                .extract()
                .map_err(|_| bad("keys must be strings".into()))?;
            let sub = if what.is_empty() {
                key.clone()
            } else {
                format!("{what}.{key}")
            };
            map.insert(key, to_json(&v, &sub)?);
        }
        return Ok(Value::Object(map));
    }
    // Python bool, or numpy's bool scalar (type name `bool_`, `bool` in numpy 2)
    let type_name: String = obj.get_type().name()?.extract()?;
    if obj.is_instance_of::<PyBool>() || type_name == "bool_" || type_name == "bool" {
        return Ok(Value::Bool(obj.is_truthy()?));
    }
    if obj.is_instance_of::<PyString>() {
        return Ok(Value::String(obj.extract()?));
    }
    if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        let mut items = Vec::new();
        for (i, v) in obj.try_iter()?.enumerate() {
            items.push(to_json(&v?, &format!("{what}[{i}]"))?);
        }
        return Ok(Value::Array(items));
    }
    if obj.is_instance_of::<PyInt>() {
        if let Ok(i) = obj.extract::<i64>() {
            return Ok(Value::Number(i.into()));
        }
    }
    // floats and numpy scalars (float64, int64, ...) through __float__
    if obj.is_instance_of::<PyFloat>() || obj.hasattr("__float__")? {
        let x: f64 = obj
            .extract()
            .or_else(|_| obj.call_method0("__float__")?.extract())?;
        return Number::from_f64(x).map(Value::Number).ok_or_else(|| {
            error(FabricError::NonFinite {
                what: what.to_string(),
            })
        });
    }
    Err(bad(format!("unsupported value of type {type_name}")))
}

/// Deep-merge `user` into `base` (objects recursively; anything else replaces).
fn deep_merge(base: &mut Value, user: Value) {
    match (base, user) {
        (Value::Object(b), Value::Object(u)) => {
            for (k, v) in u {
                match b.get_mut(&k) {
                    Some(slot) => deep_merge(slot, v),
                    None => {
                        b.insert(k, v);
                    }
                }
            }
        }
        (slot, v) => *slot = v,
    }
}

/// A JSON value as a Python object (dicts, lists, floats, ints, bools, str, None).
pub(crate) fn to_python<'py>(py: Python<'py>, v: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => PyBool::new(py, *b).to_owned().into_any(),
        Value::Number(n) => match n.as_i64() {
            Some(i) if !n.is_f64() => i.into_pyobject(py)?.into_any(),
            _ => n.as_f64().unwrap_or(f64::NAN).into_pyobject(py)?.into_any(),
        },
        Value::String(s) => s.into_pyobject(py)?.into_any(),
        Value::Array(a) => {
            let list = PyList::empty(py);
            for x in a {
                list.append(to_python(py, x)?)?;
            }
            list.into_any()
        }
        Value::Object(m) => {
            let d = PyDict::new(py);
            for (k, x) in m {
                d.set_item(k, to_python(py, x)?)?;
            }
            d.into_any()
        }
    })
}

/// Fabric configuration (immutable). `FabricConfig()` holds the defaults; `FabricConfig(d)` merges the
/// nested dict `d` over them. Sections: `mode` ("bent" | "unbent"), `joint_attraction`, `ee_position`,
/// `ee_orientation`, `joint_limits`, `self_collision`, `obstacles`, `speed` (see `to_dict()` for every
/// field and `crates/fabric-core/src/fabric/config.rs` for units and paper equations).
#[pyclass(
    frozen,
    skip_from_py_object,
    name = "FabricConfig",
    module = "gfcs._core",
    eq
)]
#[derive(Clone, PartialEq)]
pub struct PyFabricConfig {
    /// The core configuration.
    pub inner: FabricConfig,
}

impl PyFabricConfig {
    /// Configuration from a dict merged over the defaults.
    fn from_py_dict(py: Python<'_>, values: &Bound<'_, PyAny>) -> PyResult<FabricConfig> {
        let json = to_json(values, "")?.to_string();
        guarded(py, || FabricConfig::from_json_str(&json, "<dict>"))
    }

    /// The `config` argument of `Fabric(...)`: None (defaults), a `FabricConfig`, a dict or a file path.
    pub fn from_any(py: Python<'_>, config: Option<&Bound<'_, PyAny>>) -> PyResult<FabricConfig> {
        match config {
            None => Ok(FabricConfig::default()),
            Some(c) if c.is_none() => Ok(FabricConfig::default()),
            Some(c) => {
                if let Ok(cfg) = c.cast::<PyFabricConfig>() {
                    Ok(cfg.get().inner.clone())
                } else if c.is_instance_of::<PyDict>() {
                    Self::from_py_dict(py, c)
                } else {
                    let path = path_arg(c)?;
                    guarded(py, || FabricConfig::from_file(&path))
                }
            }
        }
    }
}

#[pymethods]
impl PyFabricConfig {
    /// Defaults, or the nested dict `values` merged over them.
    #[new]
    #[pyo3(signature = (values=None))]
    fn py_new(py: Python<'_>, values: Option<&Bound<'_, PyAny>>) -> PyResult<Self> {
        let inner = match values {
            Some(v) if !v.is_none() => Self::from_py_dict(py, v)?,
            _ => FabricConfig::default(),
        };
        Ok(PyFabricConfig { inner })
    }

    /// The documented defaults.
    #[staticmethod]
    fn defaults() -> Self {
        PyFabricConfig {
            inner: FabricConfig::default(),
        }
    }

    /// Read a file; the format follows the extension (.toml, .yaml/.yml, .json). Missing fields take their
    /// defaults.
    #[staticmethod]
    fn from_file(py: Python<'_>, path: &Bound<'_, PyAny>) -> PyResult<Self> {
        let path = path_arg(path)?;
        Ok(PyFabricConfig {
            inner: guarded(py, || FabricConfig::from_file(&path))?,
        })
    }

    /// Same as `FabricConfig(values)`.
    #[staticmethod]
    fn from_dict(py: Python<'_>, values: &Bound<'_, PyAny>) -> PyResult<Self> {
        Ok(PyFabricConfig {
            inner: Self::from_py_dict(py, values)?,
        })
    }

    /// Parse `text` in `format` ("toml", "yaml" or "json"); `source` names it in errors.
    #[staticmethod]
    #[pyo3(signature = (text, format="toml", source="<string>"))]
    fn from_str(py: Python<'_>, text: &str, format: &str, source: &str) -> PyResult<Self> {
        let inner = match format {
            "toml" => guarded(py, || FabricConfig::from_toml_str(text, source))?,
            "yaml" | "yml" => guarded(py, || FabricConfig::from_yaml_str(text, source))?,
            "json" => guarded(py, || FabricConfig::from_json_str(text, source))?,
            other => {
                return Err(error(FabricError::Value {
                    what: "format".into(),
                    message: format!("'{other}' is not one of toml, yaml, json"),
                }))
            }
        };
        Ok(PyFabricConfig { inner })
    }

    /// Every field as a nested dict (round-trips through `FabricConfig(d)`).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let v: Value = serde_json::from_str(&self.inner.to_json()).map_err(|e| {
            error(FabricError::Value {
                what: "config".into(),
                message: e.to_string(),
            })
        })?;
        to_python(py, &v)
    }

    /// Every field as pretty JSON text.
    fn to_json(&self) -> String {
        self.inner.to_json()
    }

    /// A copy with the nested dict `changes` (and/or keyword sections) merged over this configuration,
    /// e.g. `cfg.replace({"speed": {"desired_speed": 1.0}})` or `cfg.replace(mode="unbent")`.
    #[pyo3(signature = (changes=None, **kwargs))]
    fn replace(
        &self,
        py: Python<'_>,
        changes: Option<&Bound<'_, PyAny>>,
        kwargs: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let mut base: Value = serde_json::from_str(&self.inner.to_json()).map_err(|e| {
            error(FabricError::Value {
                what: "config".into(),
                message: e.to_string(),
            })
        })?;
        if let Some(c) = changes.filter(|c| !c.is_none()) {
            deep_merge(&mut base, to_json(c, "")?);
        }
        if let Some(k) = kwargs {
            deep_merge(&mut base, to_json(k.as_any(), "")?);
        }
        let json = base.to_string();
        Ok(PyFabricConfig {
            inner: guarded(py, || FabricConfig::from_json_str(&json, "<replace>"))?,
        })
    }

    fn __repr__(&self) -> String {
        format!(
            "FabricConfig({})",
            serde_json::to_string(&self.inner).unwrap_or_default()
        )
    }
}
