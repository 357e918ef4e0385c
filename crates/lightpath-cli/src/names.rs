//! Command-line values that are one of a list of names (`--accel`, `--sampler`,
//! `--tonemap`, `--aov`, `--simd`): a clap value parser that rejects a typo with the
//! nearest valid name ("did you mean ...?") and tells shell completions the names.

use clap::builder::{PossibleValue, TypedValueParser};
use clap::error::ErrorKind;

/// Accepts exactly one of `names`.
#[derive(Clone, Copy)]
pub struct NameParser {
    pub names: &'static [&'static str],
}

pub const ACCELS: NameParser = NameParser {
    names: lightpath::accel::AccelKind::NAMES,
};
pub const SAMPLERS: NameParser = NameParser {
    names: lightpath::sampling::Sampler::KINDS,
};
pub const AOVS: NameParser = NameParser {
    names: lightpath::integrator::AovLayer::NAMES,
};
pub const SIMD_TIERS: NameParser = NameParser {
    names: lightpath::SimdTier::NAMES,
};
pub const TONEMAPS: NameParser = NameParser {
    names: lightpath::film::Tonemap::NAMES,
};

/// The message for an unknown `value` of option `option` (e.g. `--accel`).
pub fn unknown(option: &str, value: &str, names: &[&str]) -> String {
    let hint = match lightpath::io::suggest(value, names) {
        Some(s) => format!("did you mean `{s}`? "),
        None => String::new(),
    };
    format!(
        "unknown {option} `{value}`; {hint}(known: {})",
        names.join(", ")
    )
}

impl TypedValueParser for NameParser {
    type Value = String;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &std::ffi::OsStr,
    ) -> Result<String, clap::Error> {
        let value = value.to_string_lossy();
        if self.names.contains(&value.as_ref()) {
            return Ok(value.into_owned());
        }
        let option = arg
            .and_then(|a| a.get_long())
            .map(|l| format!("--{l}"))
            .unwrap_or_else(|| "value".to_string());
        let message = unknown(&option, &value, self.names);
        Err(clap::Error::raw(ErrorKind::InvalidValue, format!("{message}\n")).with_cmd(cmd))
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        Some(Box::new(self.names.iter().map(PossibleValue::new)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suggestions() {
        assert_eq!(
            unknown("--tonemap", "agz", TONEMAPS.names),
            "unknown --tonemap `agz`; did you mean `agx`? (known: clamp, reinhard, aces, agx)"
        );
        assert!(unknown("--accel", "bhv2", ACCELS.names).contains("did you mean `bvh2`?"));
        assert!(!unknown("--sampler", "zzzzzzzz", SAMPLERS.names).contains("did you mean"));
    }
}
