//! The organ's patient: the closed-loop cardiovascular model (`cardio`) driven by what the SPH organ
//! loses. Blood that leaves the organ — liquid particles outside the solid body
//! ([`State::liquid_outside`]) — is removed from the circulating volume, multiplied by the scenario's
//! `physiology.volume_scale`; the loss never decreases (blood that re-enters the tissue is not returned).
//! Headless runs sample it at every frame (`vitals.csv`, `summary.json`); the viewer at a low rate.
//! The model's hepatic flow does not yet feed liquid into the organ (emitters are an open part of
//! issue 7).

use super::State;
use super::cardio::{CardioError, CardioModel, Vitals};
use crate::scenario::Physiology;

pub struct Patient {
    pub model: CardioModel,
    volume_scale: f64,
    /// Largest simulated volume of blood outside the organ seen so far [m³].
    lost_sim_m3: f64,
}

impl Patient {
    pub fn new(spec: &Physiology) -> Result<Patient, CardioError> {
        Ok(Patient {
            model: CardioModel::settle(spec.cardio.clone())?,
            volume_scale: spec.volume_scale,
            lost_sim_m3: 0.0,
        })
    }

    /// Simulated volume of the liquid outside the solid body: Σ m/ρ₀ over those particles [m³].
    pub fn outside_volume_m3(state: &State, rho0_liquid: f64) -> f64 {
        let s = &state.liquid;
        (0..s.len())
            .filter(|&i| s.n_s[i] < super::state::LIQUID_OUTSIDE_NS)
            .map(|i| f64::from(s.mass[i]) / rho0_liquid)
            .sum()
    }

    /// Takes the organ's state at its time: removes the new loss and advances the model to `state.t`.
    pub fn update(&mut self, state: &State, rho0_liquid: f64) -> Vitals {
        // The fractions nˢ are computed by the first step; before it there is nothing to judge.
        let outside = if state.steps > 0 { Self::outside_volume_m3(state, rho0_liquid) } else { 0.0 };
        if outside > self.lost_sim_m3 {
            self.model.remove_volume((outside - self.lost_sim_m3) * self.volume_scale);
            self.lost_sim_m3 = outside;
        }
        self.model.advance_to(state.t.max(0.0));
        self.model.vitals()
    }

    /// Simulated blood outside the organ so far [m³].
    pub fn lost_simulated_m3(&self) -> f64 {
        self.lost_sim_m3
    }
}
