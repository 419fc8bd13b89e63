//! Master estimation: the paper's raw 2nd-order predictor (SPEC §A eq. 1–4) and a
//! tracking filter for quantised masters, fed below one count from timestamped encoder
//! edges ([`EdgeEstimator`]).

mod edges;
mod filter;
mod predictor;

pub use edges::{EdgeCapture, EdgeEstimator, EdgeReading};
pub use filter::{
    MasterAhead, MasterEstimate, MasterFilter, MasterFilterCoeffs, MasterFilterConfig,
    MasterFilterError,
};
pub use predictor::{Predictor, PredictorKind};
