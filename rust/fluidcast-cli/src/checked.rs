//! clap value parsers for the numeric options that the library's table of settings
//! ([`fluidcast_backend::SETTINGS`]) checks: the CLI refuses a value where the VTK mapper,
//! ParaView and Python refuse it, with the same words.

use fluidcast_backend::Setting;

/// `s` as a number, checked as the setting behind `flag` takes it.
fn check(flag: &'static str, s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a number"))?;
    match Setting::by_flag(flag) {
        Some(setting) => setting.check(v).map_err(|e| e.to_string()),
        None => Err(format!("{flag} is in no table of settings (a bug)")),
    }
}

/// A parser of a real number for `flag`.
pub fn real(flag: &'static str) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync {
    move |s| check(flag, s)
}

/// A parser of a whole number for `flag`, into `T`.
pub fn whole<T: TryFrom<i64>>(
    flag: &'static str,
) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync {
    move |s| {
        let v = check(flag, s)?;
        T::try_from(v as i64).map_err(|_| format!("{v}: out of range"))
    }
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    use super::*;

    #[test]
    fn every_setting_with_a_flag_is_an_option_of_render() {
        let cli = crate::Cli::command();
        let render = cli.find_subcommand("render").expect("render");
        for s in fluidcast_backend::SETTINGS
            .iter()
            .filter(|s| !s.flag.is_empty())
        {
            let long = &s.flag[2..];
            assert!(
                render.get_arguments().any(|a| a.get_long() == Some(long)),
                "{} is no option of fluidcast render",
                s.flag
            );
        }
    }

    #[test]
    fn refusals_say_what_the_option_takes() {
        let e = real("--support-radius")("inf").unwrap_err();
        assert!(
            e.contains("must be 0 or a length") && e.ends_with("not inf"),
            "{e}"
        );
        assert_eq!(real("--support-radius")("0.5"), Ok(0.5));
        assert!(whole::<u32>("--grid-cell")("2.5").is_err());
        assert_eq!(whole::<u32>("--grid-cell")("4"), Ok(4));
        assert!(real("--relax")("abc").unwrap_err().contains("not a number"));
    }
}
