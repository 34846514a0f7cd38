//! The examples' command-line flags: `--name value` pairs and bare `--name` switches. Each
//! example uses what it needs of this.
#![allow(dead_code)]

/// The arguments after the program's name.
pub struct Flags(Vec<String>);

impl Flags {
    /// This process's arguments.
    pub fn from_env() -> Self {
        Flags(std::env::args().skip(1).collect())
    }

    /// The value after `flag`, if it is given.
    pub fn value(&self, flag: &str) -> Option<&str> {
        self.0
            .iter()
            .position(|a| a == flag)
            .and_then(|i| self.0.get(i + 1))
            .map(String::as_str)
    }

    /// The value after `flag` parsed, or `default` when the flag is not given.
    pub fn parse_or<T: std::str::FromStr>(&self, flag: &str, default: T) -> Result<T, T::Err> {
        self.value(flag).map_or(Ok(default), str::parse)
    }

    /// Whether the switch `flag` is given.
    pub fn has(&self, flag: &str) -> bool {
        self.0.iter().any(|a| a == flag)
    }
}
