//! The organ's patient: the closed-loop cardiovascular model (`cardio`) driven by what the SPH organ
//! loses. Blood that leaves the organ — liquid particles outside the solid body
//! ([`State::liquid_outside`]) — is removed from the circulating volume, multiplied by the scenario's
//! `physiology.volume_scale`; the loss never decreases (blood that re-enters the tissue is not returned).
//! Headless runs sample it at every frame (`vitals.csv`, `summary.json`); the viewer at a low rate.
//!
//! The other half of the loop: the model's hepatic arterial flow feeds the organ through the
//! scenario's `Hepatic` emitters. Before each stretch of stepping the driver ([`Patient::inflow`])
//! runs the model ahead to the end of a horizon, sampling its hepatic flow every
//! [`INFLOW_SAMPLE_S`], and hands the samples (÷ `volume_scale`) to the emitters as a
//! `Command::SetInflow` table — the thesis's per-step ZeroMQ exchange (§3.1.5) as a few commands
//! per simulated second, recorded with the session so that a replay needs no model. The loss then
//! reaches the model up to one horizon late, far below the baroreflex's time constants (seconds).

use super::cardio::{CardioError, CardioModel, Vitals};
use super::{Command, State};
use crate::scenario::Physiology;
use std::collections::VecDeque;

/// Sampling interval of the hepatic inflow table \[s\] (the pulse's upstroke lasts ~50 ms).
pub const INFLOW_SAMPLE_S: f64 = 1e-3;
/// How far ahead of the organ the model runs when a new table is made \[s\].
pub const INFLOW_HORIZON_S: f64 = 0.25;

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Patient {
    pub model: CardioModel,
    volume_scale: f64,
    /// Largest simulated volume of blood outside the organ seen so far \[m³\].
    lost_sim_m3: f64,
    /// Recent samples (t \[s\], hepatic flow [m³/s], its integral since t = 0 \[m³\]) of the model run ahead.
    samples: VecDeque<(f64, f64, f64)>,
}

impl Patient {
    pub fn new(spec: &Physiology) -> Result<Patient, CardioError> {
        Ok(Patient {
            model: CardioModel::settle(spec.cardio.clone())?,
            volume_scale: spec.volume_scale,
            lost_sim_m3: 0.0,
            samples: VecDeque::new(),
        })
    }

    /// Physiological per simulated volume.
    pub fn volume_scale(&self) -> f64 {
        self.volume_scale
    }

    /// The organ's hepatic inflow table from `t_now` to `until` (model run ahead, sampled every
    /// [`INFLOW_SAMPLE_S`], divided by `volume_scale`) as `SetInflow` for `emitter`.
    pub fn inflow(&mut self, emitter: usize, t_now: f64, until: f64) -> Command {
        let t_now = t_now.max(0.0);
        if self.samples.is_empty() || self.model.time() < t_now {
            self.model.advance_to(t_now);
            self.push_sample();
        }
        while self.model.time() < until {
            self.model.advance_to(self.model.time() + INFLOW_SAMPLE_S);
            self.push_sample();
        }
        // keep one sample at or before t_now (the table must cover the whole coming stretch)
        while self.samples.len() > 2 && self.samples[1].0 <= t_now {
            self.samples.pop_front();
        }
        let max = super::cpu::emit::FLOW_MAX;
        let s = self.volume_scale;
        let (times, rates) = self.samples.iter().take(max).map(|&(t, q, _)| (t, q / s)).unzip();
        Command::SetInflow { emitter, times, rates }
    }

    /// How far the inflow tables reach \[s\].
    pub fn inflow_until(&self) -> f64 {
        self.samples.back().map_or(f64::NEG_INFINITY, |s| s.0)
    }

    /// The model's hepatic inflow integrated from 0 to `t`, in simulated volume (÷ `volume_scale`)
    /// \[m³\]: linear between the kept samples (exact at sample times); `None` outside them.
    pub fn hepatic_inflow_sim_m3(&self, t: f64) -> Option<f64> {
        let k = self.samples.iter().position(|s| s.0 >= t)?;
        let (t1, _, v1) = self.samples[k];
        let v = if k == 0 || t1 == t {
            if t1 == t { v1 } else { return None }
        } else {
            let (t0, _, v0) = self.samples[k - 1];
            v0 + (v1 - v0) * (t - t0) / (t1 - t0)
        };
        Some(v / self.volume_scale)
    }

    fn push_sample(&mut self) {
        let m = &self.model;
        self.samples.push_back((m.time(), m.hepatic_flow_m3_s(), m.hepatic_volume_m3()));
    }

    /// Simulated volume of the liquid outside the solid body: Σ m/ρ₀ over those particles \[m³\].
    pub fn outside_volume_m3(state: &State, rho0_liquid: f64) -> f64 {
        let s = &state.liquid;
        (0..s.len())
            .filter(|&i| s.n_s[i] < super::state::LIQUID_OUTSIDE_NS)
            .map(|i| f64::from(s.mass[i]) / rho0_liquid)
            .sum()
    }

    /// Takes the organ's state at its time: removes the new loss and advances the model to `state.t`.
    pub fn update(&mut self, state: &State, rho0_liquid: f64) -> Vitals {
        // The fractions nˢ are computed by the first step; before it there is nothing to judge. Without
        // a solid there is no organ to leave (a pipe's inflow is not a loss).
        let outside =
            if state.steps > 0 && !state.solid.is_empty() { Self::outside_volume_m3(state, rho0_liquid) } else { 0.0 };
        if outside > self.lost_sim_m3 {
            self.model.remove_volume((outside - self.lost_sim_m3) * self.volume_scale);
            self.lost_sim_m3 = outside;
        }
        self.model.advance_to(state.t.max(0.0));
        self.model.vitals()
    }

    /// Simulated blood outside the organ so far \[m³\].
    pub fn lost_simulated_m3(&self) -> f64 {
        self.lost_sim_m3
    }
}
