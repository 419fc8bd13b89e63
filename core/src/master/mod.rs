//! Master estimation: the paper's raw 2nd-order predictor (SPEC §A eq. 1–4) and a
//! tracking filter for quantised masters.

mod filter;
mod predictor;

pub use filter::{
    MasterAhead, MasterEstimate, MasterFilter, MasterFilterCoeffs, MasterFilterConfig,
    MasterFilterError,
};
pub use predictor::{Predictor, PredictorKind};
