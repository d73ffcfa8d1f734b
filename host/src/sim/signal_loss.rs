//! Random signal loss of low-power sensors (supplement, ZJU-L5: the L5 "typically exhibits signal
//! loss … rather than returning incorrect depth values. Based on the dataset masks, the probability
//! of signal loss is approximately 30 %"): every remaining return is lost with probability `p_loss`.

use serde::{Deserialize, Serialize};

use super::error::{check_prob, SimError};
use super::frame::{Scene, ZoneEffect, ZoneGrid};
use super::truth::ZoneEvents;
use crate::rng::Rng;

/// Parameters of the random signal loss.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SignalLoss {
    /// Switch.
    pub enabled: bool,
    /// Probability that a zone with a return loses it.
    pub p_loss: f32,
}

impl ZoneEffect for SignalLoss {
    fn name(&self) -> &'static str {
        "signal_loss"
    }

    fn enabled(&self) -> bool {
        self.enabled
    }

    fn validate(&self) -> Result<(), SimError> {
        check_prob(self.name(), "p_loss", self.p_loss)
    }

    fn apply(&self, _scene: &Scene<'_>, zones: &mut ZoneGrid, rng: &mut Rng) {
        for zone in &mut zones.zones {
            if rng.f32() < self.p_loss {
                zone.lose(ZoneEvents::SIGNAL_LOSS);
            }
        }
    }
}
