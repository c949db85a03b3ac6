//! Options several commands share, from what a front end got (text from a flag, a number or a
//! string from Python) to the library's types, each with one message naming the option.

use super::{AppError, Front};
use crate::derivative::{Method, Options as DerivativeOptions};

/// A cut-off as given: the command line's text (`auto` or Hz), or Python's number.
#[derive(Debug, Clone, PartialEq)]
pub enum CutoffArg {
    Text(String),
    Hz(f64),
}

impl Default for CutoffArg {
    fn default() -> Self {
        CutoffArg::Text("auto".into())
    }
}

/// The cut-off in Hz, `None` for `auto`: a positive, finite number.
pub fn cutoff(arg: &CutoffArg, front: Front) -> Result<Option<f64>, AppError> {
    let (hz, shown) = match arg {
        CutoffArg::Text(s) if s.trim() == "auto" => return Ok(None),
        CutoffArg::Text(s) => (s.trim().parse::<f64>().ok(), s.trim().to_string()),
        CutoffArg::Hz(f) => (Some(*f), f.to_string()),
    };
    match hz {
        Some(f) if f.is_finite() && f > 0.0 => Ok(Some(f)),
        _ => Err(AppError::Input(format!(
            "{}: `{shown}` is not a positive number of Hz or `auto`",
            front.name("cutoff")
        ))),
    }
}

/// The derivative estimator by name: `butterworth` or `savgol`.
pub fn method(name: &str, front: Front) -> Result<Method, AppError> {
    match name.trim() {
        "butterworth" => Ok(Method::Butterworth),
        "savgol" => Ok(Method::SavitzkyGolay),
        other => Err(AppError::Input(format!(
            "{}: `{other}` is not an estimator — use `butterworth` or `savgol`",
            front.name("derivative")
        ))),
    }
}

/// The derivative estimator's options from the estimator's name and the cut-off.
pub fn derivative(
    name: &str,
    cut: &CutoffArg,
    front: Front,
) -> Result<DerivativeOptions, AppError> {
    Ok(DerivativeOptions {
        method: method(name, front)?,
        cutoff_hz: cutoff(cut, front)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cutoffs_and_estimators_are_checked_with_the_option_named_as_each_front_spells_it() {
        let text = |s: &str| CutoffArg::Text(s.into());
        assert_eq!(cutoff(&text(" auto "), Front::Cli).unwrap(), None);
        assert_eq!(cutoff(&text("2.5"), Front::Cli).unwrap(), Some(2.5));
        assert_eq!(
            cutoff(&CutoffArg::Hz(7.0), Front::Python).unwrap(),
            Some(7.0)
        );
        let e = cutoff(&text("-1"), Front::Cli).unwrap_err().to_string();
        assert_eq!(e, "--cutoff: `-1` is not a positive number of Hz or `auto`");
        let e = cutoff(&CutoffArg::Hz(f64::NAN), Front::Python).unwrap_err();
        assert_eq!(
            e.to_string(),
            "cutoff: `NaN` is not a positive number of Hz or `auto`"
        );
        assert_eq!(method("savgol", Front::Cli).unwrap(), Method::SavitzkyGolay);
        let e = method("spline", Front::Python).unwrap_err().to_string();
        assert!(
            e.starts_with("derivative: `spline` is not an estimator"),
            "{e}"
        );
    }
}
