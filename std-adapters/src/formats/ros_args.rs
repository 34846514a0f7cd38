//! The ROS 2 command line a node takes after `--ros-args`, and ROS 2 parameter files.
//!
//! [`RosArgs::parse`] reads what `ros2 run` and launch files pass a node:
//! - `-r FROM:=TO` / `--remap FROM:=TO`: a topic or service renamed; `__ns:=/NS` and
//!   `__node:=NAME` set the namespace and the node's name (also as `-r`);
//! - `-p NAME:=VALUE` / `--param NAME:=VALUE`: a parameter, its value read as YAML (`true`,
//!   `2`, `0.5`, `[1.0, 2.0]`, `text`);
//! - `--params-file FILE`: a parameter file, read when it is named ([`parse_params_file`]);
//! - `--log-level`, `--enable-rosout-logs` and their kin are taken and ignored;
//! - `--` or another `--ros-args` ends or restarts the section.
//!
//! A parameter file is YAML: node names (`slamesh`, `/ns/slamesh`, `/**` for every node, a
//! `*` in a name matching any text) over `ros__parameters`, over the parameters, nested maps
//! joined with dots (`a: {b: 1}` is `a.b`). Later values win: the files and `-p` in the order
//! given.
//!
//! Errors are sentences naming the argument or file and the reason.

use crate::io::error::FileError;
use std::collections::BTreeMap;
use yaml_rust2::{Yaml, YamlLoader};
use RosArgsError::{Argument, ParamsFile};

/// A parameter's value.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamValue {
    /// `true` or `false`.
    Bool(bool),
    /// An integer.
    Int(i64),
    /// A double.
    Double(f64),
    /// Text.
    Text(String),
    /// A list of doubles (integers taken as doubles).
    Doubles(Vec<f64>),
    /// A list of anything else, as text.
    Texts(Vec<String>),
}

impl ParamValue {
    /// The value as a double (an integer too).
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            ParamValue::Double(v) => Some(*v),
            ParamValue::Int(v) => Some(*v as f64),
            _ => None,
        }
    }

    /// The value as text (what a string parameter holds; other values as YAML writes them).
    pub fn as_text(&self) -> String {
        match self {
            ParamValue::Bool(b) => b.to_string(),
            ParamValue::Int(v) => v.to_string(),
            ParamValue::Double(v) => v.to_string(),
            ParamValue::Text(s) => s.clone(),
            ParamValue::Doubles(v) => format!("{v:?}"),
            ParamValue::Texts(v) => format!("{v:?}"),
        }
    }

    fn from_yaml(y: &Yaml) -> Option<Self> {
        Some(match y {
            Yaml::Boolean(b) => ParamValue::Bool(*b),
            Yaml::Integer(i) => ParamValue::Int(*i),
            Yaml::Real(_) => ParamValue::Double(y.as_f64()?),
            Yaml::String(s) => ParamValue::Text(s.clone()),
            Yaml::Array(items) => {
                let doubles: Option<Vec<f64>> = items
                    .iter()
                    .map(|v| v.as_f64().or_else(|| v.as_i64().map(|i| i as f64)))
                    .collect();
                match doubles {
                    Some(d) => ParamValue::Doubles(d),
                    None => ParamValue::Texts(
                        items
                            .iter()
                            .map(|v| {
                                ParamValue::from_yaml(v).map_or(String::new(), |p| p.as_text())
                            })
                            .collect(),
                    ),
                }
            }
            _ => return None,
        })
    }
}

/// What `--ros-args` said.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RosArgs {
    /// Renames, `from` to `to`, in order.
    pub remaps: Vec<(String, String)>,
    /// The namespace (`__ns`), if given.
    pub namespace: Option<String>,
    /// The node's name (`__node`), if given.
    pub node: Option<String>,
    /// `-p` parameters, in order.
    pub params: Vec<(String, ParamValue)>,
    /// `--params-file` files, in order.
    pub params_files: Vec<std::path::PathBuf>,
}

/// Why ROS arguments, or a parameter file they name, could not be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RosArgsError {
    /// An argument after `--ros-args`: what is wrong with it.
    Argument(String),
    /// A parameter file (`--params-file`) that could not be read, or whose text is wrong.
    File(FileError),
    /// A parameter file's text: what is wrong with it.
    ParamsFile(String),
}

impl std::fmt::Display for RosArgsError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RosArgsError::Argument(why) | RosArgsError::ParamsFile(why) => f.write_str(why),
            RosArgsError::File(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for RosArgsError {}

/// Most arguments a command line may hold: a longer one is refused, not parsed.
const MAX_ARGS: usize = 4096;
/// Nesting depth of a parameter file's maps, at most.
const MAX_DEPTH: usize = 16;

impl RosArgs {
    /// Reads `args`, the command line after the program's own arguments. Arguments outside a
    /// `--ros-args` section are an error (they belong to the program).
    pub fn parse(args: &[String]) -> Result<Self, RosArgsError> {
        if args.len() > MAX_ARGS {
            return Err(Argument(format!(
                "{} arguments, more than {MAX_ARGS}",
                args.len()
            )));
        }
        let mut out = RosArgs::default();
        let mut inside = false;
        let mut it = args.iter();
        while let Some(a) = it.next() {
            let mut value = |flag: &str| {
                it.next()
                    .cloned()
                    .ok_or_else(|| Argument(format!("{flag} needs a value")))
            };
            match a.as_str() {
                "--ros-args" => inside = true,
                "--" => inside = false,
                _ if !inside => {
                    return Err(Argument(format!(
                        "{a:?} is not a ROS argument (after --ros-args)"
                    )))
                }
                "-r" | "--remap" => out.remap(&value(a)?)?,
                "-p" | "--param" => {
                    let (name, v) = split_rule(&value(a)?)?;
                    out.params.push((name, parse_value(&v)));
                }
                "--params-file" => out.params_files.push(value(a)?.into()),
                "--log-level" | "--log-config-file" | "--log-file-name" => {
                    value(a)?;
                }
                "-e" | "--enclave" => {
                    value(a)?;
                }
                s if s.starts_with("--enable-") || s.starts_with("--disable-") => {}
                s if s.starts_with("__") => out.remap(s)?,
                other => return Err(Argument(format!("unknown ROS argument {other:?}"))),
            }
        }
        Ok(out)
    }

    fn remap(&mut self, rule: &str) -> Result<(), RosArgsError> {
        let (from, to) = split_rule(rule)?;
        match from.as_str() {
            "__ns" => self.namespace = Some(to),
            "__node" | "__name" => self.node = Some(to),
            _ => self.remaps.push((from, to)),
        }
        Ok(())
    }

    /// What `name` is renamed to, if it is.
    pub fn renamed(&self, name: &str) -> Option<&str> {
        self.remaps
            .iter()
            .rev()
            .find(|(from, _)| from == name)
            .map(|(_, to)| to.as_str())
    }

    /// Every parameter for the node `fqn` (`/ns/name`): the files' in order, then `-p`. Reads
    /// the files.
    pub fn parameters(&self, fqn: &str) -> Result<BTreeMap<String, ParamValue>, RosArgsError> {
        let mut all = BTreeMap::new();
        for f in &self.params_files {
            let text = std::fs::read_to_string(f).map_err(|e| {
                RosArgsError::File(FileError::at(
                    f,
                    format!("cannot read the parameter file: {e}"),
                ))
            })?;
            let found = parse_params_file(&text, fqn)
                .map_err(|e| RosArgsError::File(FileError::at(f, e.to_string())))?;
            all.extend(found);
        }
        all.extend(self.params.iter().cloned());
        Ok(all)
    }
}

/// `FROM:=TO`, each side non-empty.
fn split_rule(rule: &str) -> Result<(String, String), RosArgsError> {
    match rule.split_once(":=") {
        Some((a, b)) if !a.is_empty() && !b.is_empty() => Ok((a.to_string(), b.to_string())),
        _ => Err(Argument(format!("{rule:?} is not NAME:=VALUE"))),
    }
}

/// A `-p` value as YAML reads it; text when it is not a value YAML knows.
fn parse_value(text: &str) -> ParamValue {
    YamlLoader::load_from_str(text)
        .ok()
        .and_then(|d| d.first().and_then(ParamValue::from_yaml))
        .unwrap_or_else(|| ParamValue::Text(text.to_string()))
}

/// The parameters a parameter file's `text` gives the node `fqn` (`/ns/name`), in the order
/// of its node entries.
pub fn parse_params_file(
    text: &str,
    fqn: &str,
) -> Result<BTreeMap<String, ParamValue>, RosArgsError> {
    let docs =
        YamlLoader::load_from_str(text).map_err(|e| ParamsFile(format!("not YAML ({e})")))?;
    let mut out = BTreeMap::new();
    let Some(doc) = docs.first() else {
        return Ok(out);
    };
    let nodes = doc
        .as_hash()
        .ok_or_else(|| ParamsFile("not a map of node names".into()))?;
    for (name, body) in nodes {
        let name = (name.as_str()).ok_or_else(|| ParamsFile("a node name is not text".into()))?;
        if !name_matches(name, fqn) {
            continue;
        }
        let params = &body["ros__parameters"];
        if params.is_badvalue() {
            return Err(ParamsFile(format!("{name}: no ros__parameters")));
        }
        flatten(params, "", 0, &mut out).map_err(|e| ParamsFile(format!("{name}: {e}")))?;
    }
    Ok(out)
}

fn flatten(
    y: &Yaml,
    prefix: &str,
    depth: usize,
    out: &mut BTreeMap<String, ParamValue>,
) -> Result<(), RosArgsError> {
    if depth > MAX_DEPTH {
        return Err(ParamsFile(format!("maps nested deeper than {MAX_DEPTH}")));
    }
    let map = (y.as_hash()).ok_or_else(|| ParamsFile("ros__parameters is not a map".into()))?;
    for (k, v) in map {
        let key = match k {
            Yaml::String(s) => s.clone(),
            other => ParamValue::from_yaml(other)
                .map(|p| p.as_text())
                .ok_or_else(|| ParamsFile("a parameter name is not text".into()))?,
        };
        let name = if prefix.is_empty() {
            key
        } else {
            format!("{prefix}.{key}")
        };
        if v.as_hash().is_some() {
            flatten(v, &name, depth + 1, out)?;
        } else if let Some(value) = ParamValue::from_yaml(v) {
            out.insert(name, value);
        } else {
            return Err(ParamsFile(format!(
                "{name}: not a value a parameter can hold"
            )));
        }
    }
    Ok(())
}

/// Whether a parameter file's node name (`slamesh`, `/ns/slamesh`, `/**`, with `*` for any
/// text within a name and `**` for any namespaces) names the node `fqn`.
fn name_matches(pattern: &str, fqn: &str) -> bool {
    if pattern == "/**" || pattern == "**" {
        return true;
    }
    if !pattern.starts_with('/') {
        // A bare name matches the node in any namespace.
        let name = fqn.rsplit('/').next().unwrap_or(fqn);
        return glob(pattern.as_bytes(), name.as_bytes());
    }
    glob(pattern.as_bytes(), fqn.as_bytes())
}

/// `*` matches any text without a `/`, `**` any text.
fn glob(p: &[u8], s: &[u8]) -> bool {
    match p {
        [] => s.is_empty(),
        [b'*', b'*', rest @ ..] => (0..=s.len()).any(|k| glob(rest, &s[k..])),
        [b'*', rest @ ..] => (0..=s.len())
            .take_while(|&k| k == 0 || s[k - 1] != b'/')
            .any(|k| glob(rest, &s[k..])),
        [c, rest @ ..] => s.first() == Some(c) && glob(rest, &s[1..]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(s: &str) -> Vec<String> {
        s.split_whitespace().map(String::from).collect()
    }

    #[test]
    fn reads_remaps_parameters_and_names() {
        let a = RosArgs::parse(&args(
            "--ros-args -r points:=/velodyne_points -r __ns:=/robot1 -p threads:=2 \
             -p preset:=kitti -p publish_tf:=false --param scale:=0.5 -r __node:=mapper \
             --log-level debug -p lidar_in_base:=[0.1,0,1.2,0,0,0]",
        ))
        .unwrap();
        assert_eq!(a.renamed("points"), Some("/velodyne_points"));
        assert_eq!(a.renamed("odom"), None);
        assert_eq!(a.namespace.as_deref(), Some("/robot1"));
        assert_eq!(a.node.as_deref(), Some("mapper"));
        let p: BTreeMap<_, _> = a.params.into_iter().collect();
        assert_eq!(p["threads"], ParamValue::Int(2));
        assert_eq!(p["preset"], ParamValue::Text("kitti".into()));
        assert_eq!(p["publish_tf"], ParamValue::Bool(false));
        assert_eq!(p["scale"], ParamValue::Double(0.5));
        assert_eq!(
            p["lidar_in_base"],
            ParamValue::Doubles(vec![0.1, 0.0, 1.2, 0.0, 0.0, 0.0])
        );
    }

    #[test]
    fn refuses_what_it_cannot_read() {
        for bad in [
            "threads:=2",
            "--ros-args -r points",
            "--ros-args -p",
            "--ros-args -p :=3",
            "--ros-args --what",
        ] {
            assert!(RosArgs::parse(&args(bad)).is_err(), "{bad}");
        }
        assert!(RosArgs::parse(&args("--ros-args -p a:=1 -- --ros-args -r b:=c")).is_ok());
    }

    #[test]
    fn parameter_files_match_node_names_and_nest() {
        let text = "\
/**:
  ros__parameters:
    use_sim_time: true
    threads: 1
/robot1/slamesh:
  ros__parameters:
    threads: 4
    frames: {odom: odom1, base: base_link}
other:
  ros__parameters:
    threads: 9
";
        let p = parse_params_file(text, "/robot1/slamesh").unwrap();
        assert_eq!(p["use_sim_time"], ParamValue::Bool(true));
        assert_eq!(p["threads"], ParamValue::Int(4));
        assert_eq!(p["frames.odom"], ParamValue::Text("odom1".into()));
        let q = parse_params_file(text, "/slamesh").unwrap();
        assert_eq!(q["threads"], ParamValue::Int(1));
        assert!(parse_params_file("[1, 2]", "/slamesh").is_err());
        assert!(parse_params_file("slamesh: {threads: 2}", "/slamesh").is_err());
        assert!(parse_params_file("", "/slamesh").unwrap().is_empty());
    }

    #[test]
    fn names_match_as_ros_matches_them() {
        assert!(name_matches("slamesh", "/a/b/slamesh"));
        assert!(name_matches("/a/*/slamesh", "/a/b/slamesh"));
        assert!(!name_matches("/a/*", "/a/b/slamesh"));
        assert!(name_matches("/**/slamesh", "/a/b/slamesh"));
        assert!(name_matches("slam*", "/slamesh"));
        assert!(!name_matches("/other", "/slamesh"));
    }
}
