//! The error of a configuration, a value or an optimizer call. The adapter's own call-order
//! errors are [`crate::controller::AdapterError`].

use core::fmt;

/// What went wrong in a call. Small and `Copy`, so it can be returned from an interrupt
/// handler or logged without allocation; the `&'static str` names the offending parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// A value that must be finite was NaN or infinite (`"cost"`, `"start"`, ...).
    NonFinite(&'static str),
    /// `tell` was called without a pending candidate from `ask`.
    NoPendingAsk,
    /// A configuration parameter is outside its valid range (named as in the config).
    InvalidParameter(&'static str),
    /// The box is invalid in coordinate `index`: a bound is not finite or `lower >= upper`.
    InvalidBounds {
        /// The first offending coordinate.
        index: usize,
    },
    /// A parameter vector (named) lies outside the box.
    OutOfBounds(&'static str),
    /// The optimizer has stopped (converged or budget spent) and proposes nothing more.
    Stopped,
    /// A candidate is pending: tell its cost first.
    CandidatePending,
    /// Nothing has been evaluated yet.
    NoEvaluation,
    /// A ticket that is not outstanding: never handed out, already reported or cancelled,
    /// or from a generation that has ended.
    UnknownTicket,
    /// Candidates are in flight: the sequential `ask`/`tell` wait until every ticket is
    /// reported.
    InFlight,
    /// Finite input whose computation would overflow f32 (named: `"regressors"` for a model
    /// tick whose regressors or error are too large to fit); nothing was changed.
    Overflow(&'static str),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonFinite(what) => write!(f, "{what} is not finite"),
            Self::NoPendingAsk => f.write_str("tell without a pending ask"),
            Self::InvalidParameter(what) => write!(f, "invalid parameter: {what}"),
            Self::InvalidBounds { index } => write!(
                f,
                "invalid bounds in coordinate {index}: bounds must be finite with lower < upper"
            ),
            Self::OutOfBounds(what) => write!(f, "{what} lies outside the bounds"),
            Self::Stopped => f.write_str("the optimizer has stopped"),
            Self::CandidatePending => f.write_str("a candidate is pending: tell its cost first"),
            Self::NoEvaluation => f.write_str("nothing has been evaluated yet"),
            Self::UnknownTicket => f.write_str("unknown ticket: not outstanding"),
            Self::InFlight => {
                f.write_str("candidates are in flight: report or cancel their tickets first")
            }
            Self::Overflow(what) => {
                write!(f, "{what} too large: the computation would overflow f32")
            }
        }
    }
}

impl core::error::Error for Error {}

/// `Ok` when `valid`, else [`Error::InvalidParameter`] naming `parameter`: one line per range
/// check in the configurations' `validate`.
pub(crate) fn require(valid: bool, parameter: &'static str) -> Result<(), Error> {
    if valid {
        Ok(())
    } else {
        Err(Error::InvalidParameter(parameter))
    }
}

/// `Ok` when every value is finite, else [`Error::NonFinite`] naming `field`: the
/// commonest check of a decoded state.
pub(crate) fn require_finite<'a>(
    values: impl IntoIterator<Item = &'a f32>,
    field: &'static str,
) -> Result<(), Error> {
    if values.into_iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(Error::NonFinite(field))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_display_their_parameter() {
        extern crate std;
        use std::string::ToString;
        assert_eq!(
            Error::InvalidParameter("sigma").to_string(),
            "invalid parameter: sigma"
        );
        assert_eq!(Error::NonFinite("cost").to_string(), "cost is not finite");
    }
}
