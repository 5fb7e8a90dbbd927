//! Per-session metrics of a surgical session with a patient (issue 7 §4): total blood loss, peak
//! loss rate, bonds broken, and the time from the first cut to hemostasis — what an instructor
//! grades. Fed with the patient's blood loss (physiological mL, never decreasing) and the broken-bond
//! count at each sample, by headless runs (`summary.json` → `session`) and by the viewer (panel, and
//! the report when the session ends).
//!
//! Definitions (documented in the README):
//! - loss rate at t: (lost(t) − lost(t − W)) / W over the window W = [`RATE_WINDOW_S`] (at least one
//!   heartbeat, so the pulsatile loss is averaged over a beat), from the samples at or before t − W;
//! - the session starts at t = 0: samples of the relaxation (t < 0) are skipped, and the bonds already
//!   broken at the first sample are the baseline (the settling organ's breaks are not the trainee's cuts);
//! - first cut: the first sample with a bond broken beyond that baseline;
//! - hemostasis: after the first cut the loss rate rose above [`HEMOSTASIS_ML_MIN`] (the wound bled),
//!   then fell to or below it and stayed there to the end of the session; a re-bleed cancels it.

use serde::Serialize;
use std::collections::VecDeque;

/// Window of the loss rate \[s\].
pub const RATE_WINDOW_S: f64 = 1.0;
/// Loss rate at or below which bleeding counts as stopped [mL/min].
pub const HEMOSTASIS_ML_MIN: f64 = 1.0;

/// The metrics so far (`summary.json`'s `session`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct SessionReport {
    /// Blood lost by the patient \[mL\].
    pub blood_lost_ml: f64,
    /// Largest loss rate over the rate window [mL/min].
    pub peak_loss_rate_ml_min: f64,
    /// Loss rate at the end [mL/min].
    pub loss_rate_ml_min: f64,
    pub broken_bonds: u64,
    /// Time of the first broken bond \[s\].
    pub first_cut_s: Option<f64>,
    /// The wound bled faster than the hemostasis threshold at some point after the first cut.
    pub bled: bool,
    /// Time the loss rate fell to the threshold for good \[s\].
    pub hemostasis_s: Option<f64>,
    /// hemostasis_s − first_cut_s \[s\].
    pub cut_to_hemostasis_s: Option<f64>,
    pub rate_window_s: f64,
    pub hemostasis_threshold_ml_min: f64,
}

/// Accumulates [`SessionReport`] from samples in time order.
#[derive(Clone, Debug)]
pub struct SessionMetrics {
    window: VecDeque<(f64, f64)>,
    report: SessionReport,
    last_t: f64,
    /// Bonds broken at the session's first sample (t ≥ 0).
    broken_at_start: Option<u64>,
}

impl Default for SessionMetrics {
    fn default() -> Self {
        SessionMetrics {
            window: VecDeque::new(),
            report: SessionReport {
                rate_window_s: RATE_WINDOW_S,
                hemostasis_threshold_ml_min: HEMOSTASIS_ML_MIN,
                ..Default::default()
            },
            last_t: f64::NEG_INFINITY,
            broken_at_start: None,
        }
    }
}

impl SessionMetrics {
    /// One sample: time \[s\], blood lost so far \[mL\], bonds broken so far. Samples out of time order
    /// (a seek back in a replay) restart the metrics.
    pub fn push(&mut self, t: f64, lost_ml: f64, broken_bonds: u64) {
        if !(t.is_finite() && lost_ml.is_finite()) {
            return;
        }
        if t < self.last_t {
            *self = SessionMetrics::default();
        }
        self.last_t = t;
        if t < 0.0 {
            return;
        }
        let broken_bonds = broken_bonds.saturating_sub(*self.broken_at_start.get_or_insert(broken_bonds));
        let r = &mut self.report;
        r.blood_lost_ml = lost_ml;
        r.broken_bonds = broken_bonds;
        if broken_bonds > 0 && r.first_cut_s.is_none() {
            r.first_cut_s = Some(t);
        }
        self.window.push_back((t, lost_ml));
        // keep exactly one sample at or before t − W: the rate's left end
        while self.window.len() > 1 && self.window[1].0 <= t - RATE_WINDOW_S {
            self.window.pop_front();
        }
        let Some(&(t0, l0)) = self.window.front().filter(|s| s.0 <= t - RATE_WINDOW_S) else { return };
        let rate = (lost_ml - l0) / (t - t0) * 60.0;
        r.loss_rate_ml_min = rate;
        r.peak_loss_rate_ml_min = r.peak_loss_rate_ml_min.max(rate);
        let Some(cut) = r.first_cut_s else { return };
        if rate > HEMOSTASIS_ML_MIN {
            r.bled = true;
            r.hemostasis_s = None;
        } else if r.bled && r.hemostasis_s.is_none() {
            r.hemostasis_s = Some(t);
        }
        r.cut_to_hemostasis_s = r.hemostasis_s.map(|h| h - cut);
    }

    pub fn report(&self) -> &SessionReport {
        &self.report
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cut at 2 s, bleeding at 30 mL/min from 2.5 s to 6 s, then none: peak 30 mL/min, hemostasis
    /// one window after the bleeding stops (the rate is averaged over the window), 5 s after the cut.
    #[test]
    fn cut_bleed_and_hemostasis_of_a_piecewise_linear_loss() {
        let mut m = SessionMetrics::default();
        let lost = |t: f64| 0.5 * (t.clamp(2.5, 6.0) - 2.5);
        let mut t = 0.0;
        while t <= 12.0 + 1e-9 {
            m.push(t, lost(t), if t >= 2.0 { 40 } else { 0 });
            t += 0.05;
        }
        let r = m.report();
        assert!((r.peak_loss_rate_ml_min - 30.0).abs() < 1e-6, "{r:?}");
        assert_eq!(r.first_cut_s.map(|c| (c * 100.0).round()), Some(200.0));
        assert!(r.bled);
        let h = r.hemostasis_s.expect("hemostasis");
        // the windowed rate falls to ≤ 1 mL/min once at most 1/30 of the window still bleeds: at
        // 6 s + 29/30 W, or the first sample whose window start (a sample at or before t − W) is past it
        assert!((6.0 + RATE_WINDOW_S * 29.0 / 30.0 - 1e-9..=6.0 + RATE_WINDOW_S + 0.051).contains(&h), "{h}");
        assert!((r.cut_to_hemostasis_s.expect("time") - (h - 2.0)).abs() < 1e-9);
        assert!((r.blood_lost_ml - 1.75).abs() < 1e-9 && r.loss_rate_ml_min == 0.0 && r.broken_bonds == 40);
    }

    /// Bleeding that resumes cancels hemostasis; bleeding with no cut has no cut-to-hemostasis time;
    /// a seek back (time going backwards) restarts the metrics.
    #[test]
    fn rebleed_no_cut_and_restart() {
        let mut m = SessionMetrics::default();
        for k in 0..=200 {
            let t = k as f64 * 0.05;
            // bleeds 1–3 s and 6–8 s at 12 mL/min
            let lost = 0.2 * ((t.clamp(1.0, 3.0) - 1.0) + (t.clamp(6.0, 8.0) - 6.0));
            m.push(t, lost, if t >= 0.5 { 5 } else { 0 });
            if (5.0..5.01).contains(&t) {
                assert!(m.report().hemostasis_s.is_some(), "stopped after the first bleed");
            }
        }
        let r = m.report().clone();
        assert!(r.hemostasis_s.is_some_and(|h| h > 8.0), "{r:?}");
        let mut no_cut = SessionMetrics::default();
        for k in 0..=100 {
            let t = k as f64 * 0.05;
            no_cut.push(t, 0.3 * t, 0);
        }
        assert!(no_cut.report().first_cut_s.is_none() && no_cut.report().cut_to_hemostasis_s.is_none());
        assert!((no_cut.report().peak_loss_rate_ml_min - 18.0).abs() < 1e-6);
        m.push(1.0, 0.0, 0);
        assert_eq!(m.report().peak_loss_rate_ml_min, 0.0);
    }

    /// The session starts at t = 0: the relaxation's samples (t < 0) are skipped and the bonds the
    /// settling organ broke before the first sample are no cut; a cut is a bond broken after it.
    #[test]
    fn the_relaxation_is_not_part_of_the_session() {
        let mut m = SessionMetrics::default();
        for k in -20..=100 {
            let t = k as f64 * 0.05;
            // 30 bonds broke while relaxing (t < 0), 15 more at the cut at 2 s; bleeds 2–3 s
            let broken = if t < -0.5 {
                10
            } else if t < 2.0 {
                30
            } else {
                45
            };
            m.push(t, 0.5 * (t.clamp(2.0, 3.0) - 2.0), broken);
            if (1.0..1.01).contains(&t) {
                assert_eq!((m.report().first_cut_s, m.report().broken_bonds), (None, 0), "no cut yet");
            }
        }
        let r = m.report();
        assert_eq!(r.first_cut_s.map(|c| (c * 100.0).round()), Some(200.0), "{r:?}");
        assert_eq!(r.broken_bonds, 15);
        assert!(r.bled && r.hemostasis_s.is_some());
    }
}
