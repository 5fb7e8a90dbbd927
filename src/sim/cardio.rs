//! Lumped closed-loop circulation with baroreflex: the heart that perfuses (and bleeds) the liver.
//!
//! # Why
//! The SPH liver needs an inflow that beats, and a patient whose vitals answer the blood it loses. This module
//! is that patient: a zero-dimensional (lumped-parameter) closed-loop circulation that supplies the
//! instantaneous hepatic arterial inflow to the organ (`hepatic_flow_m3_s`, its exact time integral
//! `hepatic_volume_m3`), takes back what the wound loses (`remove_volume`), and reports MAP, systolic and
//! diastolic pressure, heart rate, cardiac output, blood lost and the ATLS shock class (`vitals`).
//!
//! # Model
//! The circulation and the carotid baroreflex are those of Ursino (1998), with his published parameter set
//! (Tables 1–3) as defaults:
//! * left and right ventricles with time-varying elastance: isovolumic pressure
//!   `Pmax = φ(t)·Emax·(V − Vu) + (1 − φ(t))·P0·(exp(kE·V) − 1)` (linear end-systolic, exponential
//!   end-diastolic pressure–volume relation), activation `φ = sin²(π·u·T/Tsys)` during systole
//!   (`Tsys = Tsys0 − ksys/T`), and a viscous internal resistance `R = kR·Pmax` that makes ejection
//!   afterload-dependent; inflow and outflow valves are ideal diodes behind small resistances;
//! * systemic arteries (proximal compliance `Csa` with inertance `Lsa` and resistance `Rsa`), a peripheral
//!   arteriolar node shared by the splanchnic and extrasplanchnic beds (Windkessel), splanchnic and
//!   extrasplanchnic veins, right atrium; pulmonary arteries (with inertance), pulmonary peripheral
//!   circulation, pulmonary veins, left atrium. Every compartment is linear: `P = (V − Vu)/C`;
//! * **hepatic artery branch (added here)**: a conduit resistance from the proximal aorta into a small
//!   hepatic arterial compliance, then the hepatic arteriolar/sinusoidal bed draining into the splanchnic
//!   (portal/hepatic) veins. It takes the fraction `hepatic_conductance_fraction` of Ursino's splanchnic
//!   peripheral conductance (the rest stays as the gut/spleen bed that drains into the portal vein), so the
//!   splanchnic circulation as a whole keeps Ursino's resistance at every reflex level. Its compliance is
//!   calibrated to the low-resistance, pulsatile Doppler waveform of a normal hepatic artery (resistive
//!   index ≈ 0.65). The portal inflow to the liver (`portal_flow_m3_s`) is the gut/spleen bed's flow.
//! * baroreflex (Ursino 1998): carotid sinus pressure (= proximal arterial pressure) through a linear
//!   derivative filter (`τp`, `τz`), a sigmoidal afferent firing rate, exponential sympathetic and sigmoidal
//!   vagal efferents, and first-order effectors with pure delays acting on left and right Emax, splanchnic
//!   and extrasplanchnic resistance, splanchnic and extrasplanchnic unstressed venous volume
//!   (venoconstriction) and heart period (sympathetic and vagal parts). Pure delays use a history of the
//!   efferent inputs sampled every `HISTORY_DT_S` and interpolated linearly.
//! * **hypotensive sympathetic drive (extension, `isc_*` parameters)**: the carotid baroreflex alone
//!   saturates (afferent firing at its floor, sympathetic firing at fes,0, vagal at fev,0): with Ursino's
//!   parameters the heart rate cannot exceed ≈ 108 bpm, and 35 % blood loss ends in circulatory collapse
//!   (MAP ≈ 20 mmHg) before any class III tachycardia. Below ≈ 80–60 mmHg two further inputs drive the
//!   sympathetic system in reality: the arterial chemoreceptors (stagnant hypoxia of the carotid body,
//!   Landgren & Neil 1951) and the CNS ischemic response (Guyton). They enter here as Ursino & Magosso
//!   (2000) let their chemoreceptor and CNS inputs enter: an excitatory term `x` in the sympathetic
//!   exponent, `fes = fes,∞ + (fes,0 − fes,∞)·exp(−kes·(fcs − x))`, capped at fes,max = 60 spikes/s, with
//!   `x` a first-order lag of a falling sigmoid of arterial pressure. Its size (`isc_gain_hz`) is calibrated
//!   (see the field); `isc_gain_hz = 0` gives back pure Ursino 1998.
//!
//! State variables are compartment volumes (not pressures), so the total volume is the plain sum of the
//! compartments, stressed plus unstressed, and reflex changes of unstressed volume move pressures, never
//! blood: with no wound the circulating volume is constant to round-off. Integration is classical RK4 at a
//! fixed internal step (`dt_s`, default 0.2 ms, well inside the stability limit of the fastest valve time
//! constant ≈ 5 ms); `advance_to` sub-steps and ends exactly on the requested time. The hepatic arterial
//! volume is an extra state integrated by the same RK4 steps, so it is the exact integral of the model's flow
//! up to the integrator's own error.
//!
//! Hemorrhage (`remove_volume`) takes blood from the splanchnic veins, the liver's venous side, and from the
//! other compartments in turn only if those would be emptied. Outflows of a compartment are gated to zero
//! below 0.1 mL (`V_COLLAPSE_ML`), which only acts in exsanguination beyond ≈ 55 % and keeps every volume
//! non-negative there. `CardioModel::settle` runs the model to a periodic steady state (60 s) and restarts
//! the clock at 0, so a simulation starts on a settled heart.
//!
//! Internal units are the clinical ones of the sources (mL, mmHg, s; resistance mmHg·s/mL, compliance
//! mL/mmHg, elastance mmHg/mL, inertance mmHg·s²/mL); the public flow/volume accessors are SI (m³, m³/s).
//!
//! # Sources
//! * M. Ursino, "Interaction between carotid baroregulation and the pulsating heart: a mathematical model",
//!   Am J Physiol 275 (Heart Circ Physiol 44): H1733–H1747, 1998 — circulation, heart, baroreflex and all
//!   their default parameters (total blood volume aside, see `total_blood_volume_ml`).
//! * M. Ursino, E. Magosso, "Acute cardiovascular response to isocapnic hypoxia. I. A mathematical model",
//!   Am J Physiol 279:H149–H165, 2000 — how chemoreceptor/CNS inputs add to the sympathetic efferent, and
//!   its 60 spikes/s ceiling.
//! * S. Landgren, E. Neil, "Chemoreceptor impulse activity following haemorrhage", J Physiol 112:296, 1951;
//!   J. E. Hall, "Guyton and Hall Textbook of Medical Physiology", ch. 18 (chemoreceptor and CNS ischemic
//!   responses to hypotension) — thresholds of the hypotensive drive.
//! * D. A. McNaughton, M. M. Abu-Yousef, "Doppler US of the liver made simple", RadioGraphics 31:161, 2011
//!   — normal hepatic artery resistive index.
//! * W. W. Lautt, "Hepatic Circulation: Physiology and Pathophysiology", Morgan & Claypool, 2009; C. Eipel,
//!   K. Abshagen, B. Vollmar, "Regulation of hepatic blood flow: the hepatic arterial buffer response
//!   revisited", World J Gastroenterol 16:6046–6057, 2010 — liver ≈ 25 % of cardiac output, hepatic artery
//!   ≈ 25–30 % of liver flow, i.e. ≈ 300–450 mL/min and ≈ 25 % of splanchnic arterial inflow.
//! * American College of Surgeons, "Advanced Trauma Life Support (ATLS) Student Course Manual", 10th ed.,
//!   2018 — hemorrhagic shock classes I–IV by estimated blood loss (<15, 15–30, 30–40, >40 %).
//! * Blood volume ≈ 70 mL/kg: 5000 mL for a 71 kg adult.
//! * M. Mutschler et al., "A critical reappraisal of the ATLS classification of hypovolaemic shock: does it
//!   really reflect clinical reality?", Resuscitation 84:309–313, 2013 — the ATLS heart-rate bands overlap
//!   widely in real patients.
//!
//! # Known limits
//! No transcapillary refill, no humoral vasoconstrictors (vasopressin, angiotensin, adrenal catecholamines),
//! no cardiopulmonary reflex, no respiration: blood pressure falls earlier during hemorrhage than the ATLS
//! table says (systolic ≈ 93 mmHg at 17 % loss, ≈ 60 mmHg at 35 %) while heart rate rises late (> 120 bpm
//! only from ≈ 31 % loss, and only once MAP is below ≈ 57 mmHg, since the hypotensive drive is what carries
//! it there). The class III tachycardia therefore rests on the calibrated extension and on the blood volume:
//! with Ursino's 5300 mL, 35 % loss gives 118.5 bpm (more drive raises the pressure and so limits itself).

use serde::{Deserialize, Serialize};

/// m³ → mL.
const ML_PER_M3: f64 = 1.0e6;
/// Sampling interval of the baroreflex delay history (s). Delays are resolved to this, far below the
/// shortest reflex delay (0.2 s, vagal) and time constant (1.5 s).
pub const HISTORY_DT_S: f64 = 0.005;

// ---- state vector layout -------------------------------------------------------------------------------
// Volumes (mL) of the compartments, the two inertial flows (mL/s), the cardiac phase, the baroreceptor filter,
// the eight effector increments and three running integrals.
const LV: usize = 0; // left ventricle
const SA: usize = 1; // systemic (proximal) arteries
const F_SA: usize = 2; // flow through Lsa/Rsa into the periphery, mL/s
const PER: usize = 3; // systemic peripheral (arteriolar) node, splanchnic + extrasplanchnic
const HA: usize = 4; // hepatic artery branch
const SV: usize = 5; // splanchnic veins (portal + hepatic veins)
const EV: usize = 6; // extrasplanchnic veins
const RA: usize = 7; // right atrium
const RV: usize = 8; // right ventricle
const PA: usize = 9; // pulmonary arteries
const F_PA: usize = 10; // flow through Lpa/Rpa, mL/s
const PP: usize = 11; // pulmonary peripheral
const PV: usize = 12; // pulmonary veins
const LA: usize = 13; // left atrium
const PHASE: usize = 14; // cardiac phase u (beats; fractional part is the position in the cycle)
const PTILDE: usize = 15; // baroreceptor filter output P̃ (mmHg)
const EFF: usize = 16; // 8 effector increments Δθ, see `Eff`
const HEP_VOL: usize = 24; // ∫ hepatic arterial inflow dt since t = 0 (mL)
const BEAT_P: usize = 25; // ∫ Psa dt over the current beat (mmHg·s)
const BEAT_EJ: usize = 26; // ∫ aortic outflow dt over the current beat (mL)
const ISC: usize = 27; // hypotensive (chemoreflex + CNS ischemic) sympathetic drive x (spikes/s)
const NS: usize = 28;

/// Volume-carrying entries of the state (everything that is blood).
const VOLUMES: [usize; 12] = [LV, SA, PER, HA, SV, EV, RA, RV, PA, PP, PV, LA];

/// Effector indices (offset from `EFF`).
mod eff {
    pub const EMAX_LV: usize = 0;
    pub const EMAX_RV: usize = 1;
    pub const R_SP: usize = 2;
    pub const R_EP: usize = 3;
    pub const VU_SV: usize = 4;
    pub const VU_EV: usize = 5;
    pub const T_S: usize = 6;
    pub const T_V: usize = 7;
}

type Y = [f64; NS];

// ---- errors ------------------------------------------------------------------------------------------

/// Invalid parameters. Each names the field (as `cardio.<field>` in a scenario) and what to write instead.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum CardioError {
    #[error("cardio.{field} = {value}: {requirement}")]
    InvalidParam { field: &'static str, value: f64, requirement: String },
    #[error(
        "cardio.total_blood_volume_ml = {total}: leaves only {stressed:.0} mL of stressed volume above the \
         {unstressed:.0} mL unstressed volume of the compartments (at least {min_stressed} mL needed for a \
         circulation); raise total_blood_volume_ml or lower the *_vu_ml unstressed volumes"
    )]
    VolumeBelowUnstressed { total: f64, unstressed: f64, stressed: f64, min_stressed: f64 },
}

// ---- parameters --------------------------------------------------------------------------------------

/// Every parameter of the circulation, heart, baroreflex and hepatic branch. Units are in the field names:
/// `_ml`, `_mmhg`, `_s`, `_hz` (spikes/s), `_ml_per_mmhg` (compliance), `_mmhg_s_per_ml` (resistance),
/// `_mmhg_s2_per_ml` (inertance), `_mmhg_per_ml` (elastance). Defaults are Ursino (1998) unless the field's
/// comment says otherwise; "basal" values quoted in comments are Ursino's values with the reflex at rest.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct CardioParams {
    // -- whole body / numerics --
    /// Total blood volume (mL): 5000 mL = 70 mL/kg × 71 kg (the usual adult figure). Ursino 1998 used
    /// 5300 mL; with his compartments that gives MAP 100 mmHg and 131/88 mmHg, the top of the normal range,
    /// 5000 mL gives 95 mmHg and 123/84 mmHg.
    pub total_blood_volume_ml: f64,
    /// Fixed internal RK4 step (s). 2e-4 s: stability needs < ≈ 0.01 s, accuracy of valve timing ≈ 1e-3 s.
    pub dt_s: f64,
    /// Simulated time `CardioModel::settle` runs before handing over a periodic steady state (s).
    pub settle_s: f64,

    // -- heart timing --
    /// Heart period with no autonomic input, T0 (s): 0.58 s (Ursino 1998) = intrinsic rate 103 bpm.
    pub heart_period0_s: f64,
    /// Systole duration at zero rate, Tsys0 (s): 0.5 s (Ursino 1998).
    pub systole0_s: f64,
    /// Shortening of systole with rate, ksys in Tsys = Tsys0 − ksys/T (s²): 0.075 (Ursino 1998).
    pub systole_k_s2: f64,

    // -- left ventricle --
    /// End-diastolic pressure scale P0,lv (mmHg): 1.5.
    pub lv_p0_mmhg: f64,
    /// End-diastolic stiffness kE,lv (1/mL): 0.014.
    pub lv_ke_per_ml: f64,
    /// Unstressed volume Vu,lv (mL): 16.77.
    pub lv_vu_ml: f64,
    /// End-systolic elastance without sympathetic drive, Emax,lv,0 (mmHg/mL): 2.392 (basal 2.95).
    pub lv_emax0_mmhg_per_ml: f64,
    /// Viscous resistance coefficient kR,lv (s/mL): 3.75e-4.
    pub lv_kr_s_per_ml: f64,

    // -- right ventricle --
    /// P0,rv (mmHg): 1.5.
    pub rv_p0_mmhg: f64,
    /// kE,rv (1/mL): 0.011.
    pub rv_ke_per_ml: f64,
    /// Vu,rv (mL): 40.8.
    pub rv_vu_ml: f64,
    /// Emax,rv,0 (mmHg/mL): 1.412 (basal 1.75).
    pub rv_emax0_mmhg_per_ml: f64,
    /// kR,rv (s/mL): 1.4e-3.
    pub rv_kr_s_per_ml: f64,

    // -- atria (passive) and atrioventricular valves --
    /// Left atrial compliance Cla (mL/mmHg): 19.23.
    pub la_c_ml_per_mmhg: f64,
    /// Mitral resistance Rla (mmHg·s/mL): 2.5e-3.
    pub la_r_mmhg_s_per_ml: f64,
    /// Left atrial unstressed volume (mL): 25.
    pub la_vu_ml: f64,
    /// Right atrial compliance Cra (mL/mmHg): 31.25.
    pub ra_c_ml_per_mmhg: f64,
    /// Tricuspid resistance Rra (mmHg·s/mL): 2.5e-3.
    pub ra_r_mmhg_s_per_ml: f64,
    /// Right atrial unstressed volume (mL): 25.
    pub ra_vu_ml: f64,

    // -- pulmonary circulation --
    /// Pulmonary arterial compliance Cpa (mL/mmHg): 0.76.
    pub pa_c_ml_per_mmhg: f64,
    /// Pulmonary arterial resistance Rpa (mmHg·s/mL): 0.023.
    pub pa_r_mmhg_s_per_ml: f64,
    /// Pulmonary arterial inertance Lpa (mmHg·s²/mL): 1.8e-4.
    pub pa_l_mmhg_s2_per_ml: f64,
    /// Pulmonary arterial unstressed volume (mL): 0.
    pub pa_vu_ml: f64,
    /// Pulmonary peripheral compliance Cpp (mL/mmHg): 5.80.
    pub pp_c_ml_per_mmhg: f64,
    /// Pulmonary peripheral resistance Rpp (mmHg·s/mL): 0.0894.
    pub pp_r_mmhg_s_per_ml: f64,
    /// Pulmonary peripheral unstressed volume (mL): 123.
    pub pp_vu_ml: f64,
    /// Pulmonary venous compliance Cpv (mL/mmHg): 25.37.
    pub pv_c_ml_per_mmhg: f64,
    /// Pulmonary venous resistance Rpv (mmHg·s/mL): 0.0056.
    pub pv_r_mmhg_s_per_ml: f64,
    /// Pulmonary venous unstressed volume (mL): 120.
    pub pv_vu_ml: f64,

    // -- systemic circulation --
    /// Systemic (proximal) arterial compliance Csa (mL/mmHg): 0.28.
    pub sa_c_ml_per_mmhg: f64,
    /// Systemic arterial resistance Rsa (mmHg·s/mL): 0.06.
    pub sa_r_mmhg_s_per_ml: f64,
    /// Systemic arterial inertance Lsa (mmHg·s²/mL): 2.2e-4.
    pub sa_l_mmhg_s2_per_ml: f64,
    /// Systemic arterial unstressed volume (mL): 0.
    pub sa_vu_ml: f64,
    /// Splanchnic peripheral compliance Csp (mL/mmHg): 2.05.
    pub sp_c_ml_per_mmhg: f64,
    /// Splanchnic peripheral resistance without sympathetic drive, Rsp,0 (mmHg·s/mL): 2.49 (basal 3.307).
    /// This is the whole splanchnic bed; `hepatic_conductance_fraction` of it is the hepatic artery.
    pub sp_r0_mmhg_s_per_ml: f64,
    /// Splanchnic peripheral unstressed volume (mL): 274.4.
    pub sp_vu_ml: f64,
    /// Extrasplanchnic peripheral compliance Cep (mL/mmHg): 1.67.
    pub ep_c_ml_per_mmhg: f64,
    /// Extrasplanchnic peripheral resistance without sympathetic drive, Rep,0 (mmHg·s/mL): 0.78 (basal 1.407).
    pub ep_r0_mmhg_s_per_ml: f64,
    /// Extrasplanchnic peripheral unstressed volume (mL): 336.6.
    pub ep_vu_ml: f64,
    /// Splanchnic venous compliance Csv (mL/mmHg): 61.11.
    pub sv_c_ml_per_mmhg: f64,
    /// Splanchnic venous resistance Rsv (mmHg·s/mL): 0.038.
    pub sv_r_mmhg_s_per_ml: f64,
    /// Splanchnic venous unstressed volume without sympathetic drive, Vu,sv,0 (mL): 1435.4 (basal 1121).
    pub sv_vu0_ml: f64,
    /// Extrasplanchnic venous compliance Cev (mL/mmHg): 50.
    pub ev_c_ml_per_mmhg: f64,
    /// Extrasplanchnic venous resistance Rev (mmHg·s/mL): 0.016.
    pub ev_r_mmhg_s_per_ml: f64,
    /// Extrasplanchnic venous unstressed volume without sympathetic drive, Vu,ev,0 (mL): 1537 (basal 1375).
    pub ev_vu0_ml: f64,

    // -- hepatic artery branch (this module; sources in the field comments) --
    /// Share of the splanchnic peripheral conductance that is the hepatic artery (–): 0.25. All splanchnic
    /// arterial inflow passes the liver (portal or arterial), and the hepatic artery is ≈ 25–30 % of liver
    /// flow (Lautt 2009; Eipel 2010), so ≈ 25 % of the splanchnic bed; with Ursino's ≈ 1.5 L/min splanchnic
    /// flow this gives ≈ 370 mL/min.
    pub hepatic_conductance_fraction: f64,
    /// Conduit resistance celiac trunk → common/proper hepatic artery (mmHg·s/mL): 0.3 (Poiseuille, ≈ 4.5 mm
    /// diameter over ≈ 10 cm, blood 3.5 mPa·s); small beside the ≈ 13 mmHg·s/mL of the hepatic bed.
    pub ha_conduit_r_mmhg_s_per_ml: f64,
    /// Hepatic arterial compliance (mL/mmHg): 0.008, calibrated so that the inflow waveform has the resistive
    /// index (peak − end-diastolic)/peak ≈ 0.65 of a normal hepatic artery on Doppler (0.55–0.7, McNaughton &
    /// Abu-Yousef, RadioGraphics 31:161, 2011). 0.002 gives RI 0.36, 0.015 gives 0.86.
    pub ha_c_ml_per_mmhg: f64,
    /// Hepatic arterial unstressed volume (mL): 0, as Ursino's systemic arteries.
    pub ha_vu_ml: f64,

    // -- baroreceptors (carotid sinus) --
    /// Carotid pressure at the centre of the afferent sigmoid, Pn (mmHg): 92.
    pub baro_pn_mmhg: f64,
    /// Slope parameter of the afferent sigmoid, ka (mmHg): 11.758.
    pub baro_ka_mmhg: f64,
    /// Lower afferent saturation fmin (spikes/s): 2.52.
    pub baro_fmin_hz: f64,
    /// Upper afferent saturation fmax (spikes/s): 47.78.
    pub baro_fmax_hz: f64,
    /// Zero (rate sensitivity) time constant τz (s): 6.37.
    pub baro_tau_z_s: f64,
    /// Pole time constant τp (s): 2.076.
    pub baro_tau_p_s: f64,

    // -- efferent pathways --
    /// Sympathetic firing at infinite afferent firing, fes,∞ (spikes/s): 2.10.
    pub symp_finf_hz: f64,
    /// Sympathetic firing at zero afferent firing, fes,0 (spikes/s): 16.11.
    pub symp_f0_hz: f64,
    /// Sympathetic exponential constant kes (s): 0.0675.
    pub symp_k_s: f64,
    /// Sympathetic threshold of the effectors, fes,min (spikes/s): 2.66.
    pub symp_fmin_hz: f64,
    /// Vagal firing at zero afferent firing, fev,0 (spikes/s): 3.2.
    pub vagal_f0_hz: f64,
    /// Vagal firing at infinite afferent firing, fev,∞ (spikes/s): 6.3.
    pub vagal_finf_hz: f64,
    /// Afferent firing at the vagal sigmoid centre, fcs,0 (spikes/s): 25.
    pub vagal_fcs0_hz: f64,
    /// Vagal sigmoid slope kev (spikes/s): 7.06.
    pub vagal_k_hz: f64,

    // -- effectors: gain G, time constant τ, pure delay D (Ursino 1998 Table 3) --
    /// G of Emax,lv (mmHg/mL per spikes/s): 0.475.
    pub eff_emax_lv_gain: f64,
    /// τ of Emax,lv (s): 8.
    pub eff_emax_lv_tau_s: f64,
    /// D of Emax,lv (s): 2.
    pub eff_emax_lv_delay_s: f64,
    /// G of Emax,rv (mmHg/mL per spikes/s): 0.282.
    pub eff_emax_rv_gain: f64,
    /// τ of Emax,rv (s): 8.
    pub eff_emax_rv_tau_s: f64,
    /// D of Emax,rv (s): 2.
    pub eff_emax_rv_delay_s: f64,
    /// G of Rsp (mmHg·s/mL per spikes/s): 0.695.
    pub eff_r_sp_gain: f64,
    /// τ of Rsp (s): 6.
    pub eff_r_sp_tau_s: f64,
    /// D of Rsp (s): 2.
    pub eff_r_sp_delay_s: f64,
    /// G of Rep (mmHg·s/mL per spikes/s): 0.53.
    pub eff_r_ep_gain: f64,
    /// τ of Rep (s): 6.
    pub eff_r_ep_tau_s: f64,
    /// D of Rep (s): 2.
    pub eff_r_ep_delay_s: f64,
    /// G of Vu,sv (mL per spikes/s): −265.4 (venoconstriction: negative).
    pub eff_vu_sv_gain: f64,
    /// τ of Vu,sv (s): 20.
    pub eff_vu_sv_tau_s: f64,
    /// D of Vu,sv (s): 5.
    pub eff_vu_sv_delay_s: f64,
    /// G of Vu,ev (mL per spikes/s): −132.5.
    pub eff_vu_ev_gain: f64,
    /// τ of Vu,ev (s): 20.
    pub eff_vu_ev_tau_s: f64,
    /// D of Vu,ev (s): 5.
    pub eff_vu_ev_delay_s: f64,
    /// G of the sympathetic heart-period term Ts (s per spikes/s): −0.13.
    pub eff_t_s_gain: f64,
    /// τ of Ts (s): 2.
    pub eff_t_s_tau_s: f64,
    /// D of Ts (s): 2.
    pub eff_t_s_delay_s: f64,
    /// G of the vagal heart-period term Tv (s per spikes/s): 0.09.
    pub eff_t_v_gain: f64,
    /// τ of Tv (s): 1.5.
    pub eff_t_v_tau_s: f64,
    /// D of Tv (s): 0.2.
    pub eff_t_v_delay_s: f64,

    // -- hypotensive sympathetic drive (extension to Ursino 1998, see module docs) --
    /// Largest extra sympathetic excitation x (afferent-equivalent spikes/s) from the chemoreflex and CNS
    /// ischemic response at very low arterial pressure: 20. CALIBRATED, not a literature value: it is the
    /// smallest round value with which 35 % blood loss gives HR > 120 (15 gives ≈ 127 bpm at 5000 mL but
    /// < 120 at 5300 mL); at full drive sympathetic firing reaches ≈ 48 spikes/s, inside the 60 spikes/s
    /// ceiling of Ursino & Magosso (2000). 0 switches the extension off (pure Ursino 1998).
    pub isc_gain_hz: f64,
    /// Arterial pressure at half the drive (mmHg): 60. Chemoreceptors fire with stagnant hypoxia below
    /// ≈ 80 mmHg (Landgren & Neil, J Physiol 112:296, 1951) and the CNS ischemic response starts below
    /// ≈ 60 mmHg, maximal at 15–20 mmHg (Guyton & Hall, Textbook of Medical Physiology, ch. 18); the lumped
    /// sigmoid is 8 % on at 80 mmHg and 92 % at 40 mmHg.
    pub isc_p50_mmhg: f64,
    /// Slope of the drive's sigmoid (mmHg): 8 (see `isc_p50_mmhg`).
    pub isc_k_mmhg: f64,
    /// Time constant of the drive (s): 20, the order of the CNS ischemic response's in the Ursino–Magosso
    /// models (the chemoreceptors themselves are faster, a few seconds).
    pub isc_tau_s: f64,
    /// Vagal withdrawal per unit drive (–): fev is reduced by this × x (floored at 0). 0 by default (not
    /// needed; Ursino & Magosso's chemoreflex raises vagal tone directly and lowers it through lung
    /// inflation, a balance this model does not resolve).
    pub isc_vagal_weight: f64,
    /// Upper saturation of sympathetic efferent firing, fes,max (spikes/s): 60 (Ursino & Magosso 2000).
    pub symp_fmax_hz: f64,
}

impl Default for CardioParams {
    fn default() -> Self {
        CardioParams {
            total_blood_volume_ml: 5000.0,
            dt_s: 2.0e-4,
            settle_s: 60.0,
            heart_period0_s: 0.58,
            systole0_s: 0.5,
            systole_k_s2: 0.075,
            lv_p0_mmhg: 1.5,
            lv_ke_per_ml: 0.014,
            lv_vu_ml: 16.77,
            lv_emax0_mmhg_per_ml: 2.392,
            lv_kr_s_per_ml: 3.75e-4,
            rv_p0_mmhg: 1.5,
            rv_ke_per_ml: 0.011,
            rv_vu_ml: 40.8,
            rv_emax0_mmhg_per_ml: 1.412,
            rv_kr_s_per_ml: 1.4e-3,
            la_c_ml_per_mmhg: 19.23,
            la_r_mmhg_s_per_ml: 2.5e-3,
            la_vu_ml: 25.0,
            ra_c_ml_per_mmhg: 31.25,
            ra_r_mmhg_s_per_ml: 2.5e-3,
            ra_vu_ml: 25.0,
            pa_c_ml_per_mmhg: 0.76,
            pa_r_mmhg_s_per_ml: 0.023,
            pa_l_mmhg_s2_per_ml: 1.8e-4,
            pa_vu_ml: 0.0,
            pp_c_ml_per_mmhg: 5.80,
            pp_r_mmhg_s_per_ml: 0.0894,
            pp_vu_ml: 123.0,
            pv_c_ml_per_mmhg: 25.37,
            pv_r_mmhg_s_per_ml: 0.0056,
            pv_vu_ml: 120.0,
            sa_c_ml_per_mmhg: 0.28,
            sa_r_mmhg_s_per_ml: 0.06,
            sa_l_mmhg_s2_per_ml: 2.2e-4,
            sa_vu_ml: 0.0,
            sp_c_ml_per_mmhg: 2.05,
            sp_r0_mmhg_s_per_ml: 2.49,
            sp_vu_ml: 274.4,
            ep_c_ml_per_mmhg: 1.67,
            ep_r0_mmhg_s_per_ml: 0.78,
            ep_vu_ml: 336.6,
            sv_c_ml_per_mmhg: 61.11,
            sv_r_mmhg_s_per_ml: 0.038,
            sv_vu0_ml: 1435.4,
            ev_c_ml_per_mmhg: 50.0,
            ev_r_mmhg_s_per_ml: 0.016,
            ev_vu0_ml: 1537.0,
            hepatic_conductance_fraction: 0.25,
            ha_conduit_r_mmhg_s_per_ml: 0.3,
            ha_c_ml_per_mmhg: 0.008,
            ha_vu_ml: 0.0,
            baro_pn_mmhg: 92.0,
            baro_ka_mmhg: 11.758,
            baro_fmin_hz: 2.52,
            baro_fmax_hz: 47.78,
            baro_tau_z_s: 6.37,
            baro_tau_p_s: 2.076,
            symp_finf_hz: 2.10,
            symp_f0_hz: 16.11,
            symp_k_s: 0.0675,
            symp_fmin_hz: 2.66,
            vagal_f0_hz: 3.2,
            vagal_finf_hz: 6.3,
            vagal_fcs0_hz: 25.0,
            vagal_k_hz: 7.06,
            eff_emax_lv_gain: 0.475,
            eff_emax_lv_tau_s: 8.0,
            eff_emax_lv_delay_s: 2.0,
            eff_emax_rv_gain: 0.282,
            eff_emax_rv_tau_s: 8.0,
            eff_emax_rv_delay_s: 2.0,
            eff_r_sp_gain: 0.695,
            eff_r_sp_tau_s: 6.0,
            eff_r_sp_delay_s: 2.0,
            eff_r_ep_gain: 0.53,
            eff_r_ep_tau_s: 6.0,
            eff_r_ep_delay_s: 2.0,
            eff_vu_sv_gain: -265.4,
            eff_vu_sv_tau_s: 20.0,
            eff_vu_sv_delay_s: 5.0,
            eff_vu_ev_gain: -132.5,
            eff_vu_ev_tau_s: 20.0,
            eff_vu_ev_delay_s: 5.0,
            eff_t_s_gain: -0.13,
            eff_t_s_tau_s: 2.0,
            eff_t_s_delay_s: 2.0,
            eff_t_v_gain: 0.09,
            eff_t_v_tau_s: 1.5,
            eff_t_v_delay_s: 0.2,
            isc_gain_hz: 20.0,
            isc_p50_mmhg: 60.0,
            isc_k_mmhg: 8.0,
            isc_tau_s: 20.0,
            isc_vagal_weight: 0.0,
            symp_fmax_hz: 60.0,
        }
    }
}

/// Least stressed volume (mL) a parameter set must leave for a circulation to exist at all.
const MIN_STRESSED_ML: f64 = 300.0;

fn check(field: &'static str, value: f64, lo: f64, hi: f64, unit: &str) -> Result<(), CardioError> {
    // NaN and ±inf fail the finiteness test first.
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        let requirement = if value.is_finite() {
            format!("must be in {lo}..{hi} {unit}")
        } else {
            format!("is not a finite number; give a value in {lo}..{hi} {unit}")
        };
        Err(CardioError::InvalidParam { field, value, requirement })
    }
}

impl CardioParams {
    /// Checks every field is finite and inside a physically meaningful range (wide: 1/10 to 10× the adult
    /// defaults for most), and that the blood volume exceeds the unstressed volume of the compartments.
    pub fn validate(&self) -> Result<(), CardioError> {
        const C: &str = "mL/mmHg";
        const R: &str = "mmHg·s/mL";
        const L: &str = "mmHg·s²/mL";
        const E: &str = "mmHg/mL";
        check("total_blood_volume_ml", self.total_blood_volume_ml, 500.0, 15000.0, "mL (adult ≈ 70 mL/kg)")?;
        check("dt_s", self.dt_s, 1.0e-5, 1.0e-3, "s (RK4 step; 2e-4 recommended)")?;
        check("settle_s", self.settle_s, 0.0, 3600.0, "s")?;
        check("heart_period0_s", self.heart_period0_s, 0.24, 3.0, "s (intrinsic period; 0.58 s = 103 bpm)")?;
        check("systole0_s", self.systole0_s, 0.1, 1.0, "s")?;
        check("systole_k_s2", self.systole_k_s2, 0.0, 0.2, "s²")?;
        check("lv_p0_mmhg", self.lv_p0_mmhg, 0.01, 20.0, "mmHg")?;
        check("lv_ke_per_ml", self.lv_ke_per_ml, 1.0e-3, 0.2, "1/mL")?;
        check("lv_vu_ml", self.lv_vu_ml, 0.0, 200.0, "mL")?;
        check("lv_emax0_mmhg_per_ml", self.lv_emax0_mmhg_per_ml, 0.1, 20.0, E)?;
        check("lv_kr_s_per_ml", self.lv_kr_s_per_ml, 0.0, 0.01, "s/mL")?;
        check("rv_p0_mmhg", self.rv_p0_mmhg, 0.01, 20.0, "mmHg")?;
        check("rv_ke_per_ml", self.rv_ke_per_ml, 1.0e-3, 0.2, "1/mL")?;
        check("rv_vu_ml", self.rv_vu_ml, 0.0, 200.0, "mL")?;
        check("rv_emax0_mmhg_per_ml", self.rv_emax0_mmhg_per_ml, 0.05, 20.0, E)?;
        check("rv_kr_s_per_ml", self.rv_kr_s_per_ml, 0.0, 0.01, "s/mL")?;
        check("la_c_ml_per_mmhg", self.la_c_ml_per_mmhg, 1.0, 200.0, C)?;
        check("la_r_mmhg_s_per_ml", self.la_r_mmhg_s_per_ml, 1.0e-4, 0.1, R)?;
        check("la_vu_ml", self.la_vu_ml, 0.0, 200.0, "mL")?;
        check("ra_c_ml_per_mmhg", self.ra_c_ml_per_mmhg, 1.0, 300.0, C)?;
        check("ra_r_mmhg_s_per_ml", self.ra_r_mmhg_s_per_ml, 1.0e-4, 0.1, R)?;
        check("ra_vu_ml", self.ra_vu_ml, 0.0, 200.0, "mL")?;
        check("pa_c_ml_per_mmhg", self.pa_c_ml_per_mmhg, 0.05, 20.0, C)?;
        check("pa_r_mmhg_s_per_ml", self.pa_r_mmhg_s_per_ml, 1.0e-3, 1.0, R)?;
        check("pa_l_mmhg_s2_per_ml", self.pa_l_mmhg_s2_per_ml, 1.0e-5, 1.0e-2, L)?;
        check("pa_vu_ml", self.pa_vu_ml, 0.0, 500.0, "mL")?;
        check("pp_c_ml_per_mmhg", self.pp_c_ml_per_mmhg, 0.5, 100.0, C)?;
        check("pp_r_mmhg_s_per_ml", self.pp_r_mmhg_s_per_ml, 1.0e-3, 2.0, R)?;
        check("pp_vu_ml", self.pp_vu_ml, 0.0, 1000.0, "mL")?;
        check("pv_c_ml_per_mmhg", self.pv_c_ml_per_mmhg, 1.0, 300.0, C)?;
        check("pv_r_mmhg_s_per_ml", self.pv_r_mmhg_s_per_ml, 1.0e-4, 1.0, R)?;
        check("pv_vu_ml", self.pv_vu_ml, 0.0, 1000.0, "mL")?;
        check("sa_c_ml_per_mmhg", self.sa_c_ml_per_mmhg, 0.02, 5.0, C)?;
        check("sa_r_mmhg_s_per_ml", self.sa_r_mmhg_s_per_ml, 1.0e-3, 1.0, R)?;
        check("sa_l_mmhg_s2_per_ml", self.sa_l_mmhg_s2_per_ml, 1.0e-5, 1.0e-2, L)?;
        check("sa_vu_ml", self.sa_vu_ml, 0.0, 1000.0, "mL")?;
        check("sp_c_ml_per_mmhg", self.sp_c_ml_per_mmhg, 0.1, 50.0, C)?;
        check("sp_r0_mmhg_s_per_ml", self.sp_r0_mmhg_s_per_ml, 0.1, 50.0, R)?;
        check("sp_vu_ml", self.sp_vu_ml, 0.0, 3000.0, "mL")?;
        check("ep_c_ml_per_mmhg", self.ep_c_ml_per_mmhg, 0.1, 50.0, C)?;
        check("ep_r0_mmhg_s_per_ml", self.ep_r0_mmhg_s_per_ml, 0.05, 50.0, R)?;
        check("ep_vu_ml", self.ep_vu_ml, 0.0, 3000.0, "mL")?;
        check("sv_c_ml_per_mmhg", self.sv_c_ml_per_mmhg, 5.0, 500.0, C)?;
        check("sv_r_mmhg_s_per_ml", self.sv_r_mmhg_s_per_ml, 1.0e-3, 1.0, R)?;
        check("sv_vu0_ml", self.sv_vu0_ml, 0.0, 5000.0, "mL")?;
        check("ev_c_ml_per_mmhg", self.ev_c_ml_per_mmhg, 5.0, 500.0, C)?;
        check("ev_r_mmhg_s_per_ml", self.ev_r_mmhg_s_per_ml, 1.0e-3, 1.0, R)?;
        check("ev_vu0_ml", self.ev_vu0_ml, 0.0, 5000.0, "mL")?;
        check("hepatic_conductance_fraction", self.hepatic_conductance_fraction, 0.01, 0.9, "(share, 0.25 typical)")?;
        check("ha_conduit_r_mmhg_s_per_ml", self.ha_conduit_r_mmhg_s_per_ml, 1.0e-3, 10.0, R)?;
        check("ha_c_ml_per_mmhg", self.ha_c_ml_per_mmhg, 1.0e-3, 1.0, C)?;
        check("ha_vu_ml", self.ha_vu_ml, 0.0, 100.0, "mL")?;
        check("baro_pn_mmhg", self.baro_pn_mmhg, 40.0, 200.0, "mmHg")?;
        check("baro_ka_mmhg", self.baro_ka_mmhg, 1.0, 50.0, "mmHg")?;
        check("baro_fmin_hz", self.baro_fmin_hz, 0.0, 20.0, "spikes/s")?;
        check("baro_fmax_hz", self.baro_fmax_hz, 5.0, 200.0, "spikes/s")?;
        check("baro_tau_z_s", self.baro_tau_z_s, 0.0, 60.0, "s")?;
        check("baro_tau_p_s", self.baro_tau_p_s, 0.05, 60.0, "s")?;
        check("symp_finf_hz", self.symp_finf_hz, 0.0, 20.0, "spikes/s")?;
        check("symp_f0_hz", self.symp_f0_hz, 1.0, 60.0, "spikes/s")?;
        check("symp_k_s", self.symp_k_s, 1.0e-3, 1.0, "s")?;
        check("symp_fmin_hz", self.symp_fmin_hz, 0.0, 20.0, "spikes/s")?;
        check("vagal_f0_hz", self.vagal_f0_hz, 0.0, 20.0, "spikes/s")?;
        check("vagal_finf_hz", self.vagal_finf_hz, 0.0, 40.0, "spikes/s")?;
        check("vagal_fcs0_hz", self.vagal_fcs0_hz, 0.0, 100.0, "spikes/s")?;
        check("vagal_k_hz", self.vagal_k_hz, 0.1, 50.0, "spikes/s")?;
        check("isc_gain_hz", self.isc_gain_hz, 0.0, 60.0, "spikes/s (0 = off)")?;
        check("isc_p50_mmhg", self.isc_p50_mmhg, 10.0, 120.0, "mmHg")?;
        check("isc_k_mmhg", self.isc_k_mmhg, 1.0, 50.0, "mmHg")?;
        check("isc_tau_s", self.isc_tau_s, 0.5, 600.0, "s")?;
        check("isc_vagal_weight", self.isc_vagal_weight, 0.0, 1.0, "(–)")?;
        check("symp_fmax_hz", self.symp_fmax_hz, 1.0, 200.0, "spikes/s")?;
        for (name, gain, tau, delay, g_lo, g_hi) in self.effector_fields() {
            check(name[0], gain, g_lo, g_hi, "(effector gain)")?;
            check(name[1], tau, 0.1, 300.0, "s")?;
            check(name[2], delay, 0.0, 30.0, "s")?;
        }
        if self.baro_fmax_hz <= self.baro_fmin_hz {
            return Err(CardioError::InvalidParam {
                field: "baro_fmax_hz",
                value: self.baro_fmax_hz,
                requirement: format!("must exceed baro_fmin_hz = {}", self.baro_fmin_hz),
            });
        }
        if self.symp_f0_hz <= self.symp_finf_hz {
            return Err(CardioError::InvalidParam {
                field: "symp_f0_hz",
                value: self.symp_f0_hz,
                requirement: format!(
                    "must exceed symp_finf_hz = {} (sympathetic falls as pressure rises)",
                    self.symp_finf_hz
                ),
            });
        }
        let unstressed = self.unstressed_total_ml();
        let stressed = self.total_blood_volume_ml - unstressed;
        if stressed < MIN_STRESSED_ML {
            return Err(CardioError::VolumeBelowUnstressed {
                total: self.total_blood_volume_ml,
                unstressed,
                stressed,
                min_stressed: MIN_STRESSED_ML,
            });
        }
        Ok(())
    }

    /// (field names, gain, τ, delay, gain range) of the eight effectors, in `eff` order.
    #[allow(clippy::type_complexity)]
    fn effector_fields(&self) -> [([&'static str; 3], f64, f64, f64, f64, f64); 8] {
        [
            (
                ["eff_emax_lv_gain", "eff_emax_lv_tau_s", "eff_emax_lv_delay_s"],
                self.eff_emax_lv_gain,
                self.eff_emax_lv_tau_s,
                self.eff_emax_lv_delay_s,
                0.0,
                5.0,
            ),
            (
                ["eff_emax_rv_gain", "eff_emax_rv_tau_s", "eff_emax_rv_delay_s"],
                self.eff_emax_rv_gain,
                self.eff_emax_rv_tau_s,
                self.eff_emax_rv_delay_s,
                0.0,
                5.0,
            ),
            (
                ["eff_r_sp_gain", "eff_r_sp_tau_s", "eff_r_sp_delay_s"],
                self.eff_r_sp_gain,
                self.eff_r_sp_tau_s,
                self.eff_r_sp_delay_s,
                0.0,
                10.0,
            ),
            (
                ["eff_r_ep_gain", "eff_r_ep_tau_s", "eff_r_ep_delay_s"],
                self.eff_r_ep_gain,
                self.eff_r_ep_tau_s,
                self.eff_r_ep_delay_s,
                0.0,
                10.0,
            ),
            (
                ["eff_vu_sv_gain", "eff_vu_sv_tau_s", "eff_vu_sv_delay_s"],
                self.eff_vu_sv_gain,
                self.eff_vu_sv_tau_s,
                self.eff_vu_sv_delay_s,
                -1000.0,
                0.0,
            ),
            (
                ["eff_vu_ev_gain", "eff_vu_ev_tau_s", "eff_vu_ev_delay_s"],
                self.eff_vu_ev_gain,
                self.eff_vu_ev_tau_s,
                self.eff_vu_ev_delay_s,
                -1000.0,
                0.0,
            ),
            (
                ["eff_t_s_gain", "eff_t_s_tau_s", "eff_t_s_delay_s"],
                self.eff_t_s_gain,
                self.eff_t_s_tau_s,
                self.eff_t_s_delay_s,
                -1.0,
                0.0,
            ),
            (
                ["eff_t_v_gain", "eff_t_v_tau_s", "eff_t_v_delay_s"],
                self.eff_t_v_gain,
                self.eff_t_v_tau_s,
                self.eff_t_v_delay_s,
                0.0,
                1.0,
            ),
        ]
    }

    /// Sum of the compartments' unstressed volumes with no sympathetic drive (mL).
    fn unstressed_total_ml(&self) -> f64 {
        self.lv_vu_ml
            + self.rv_vu_ml
            + self.la_vu_ml
            + self.ra_vu_ml
            + self.pa_vu_ml
            + self.pp_vu_ml
            + self.pv_vu_ml
            + self.sa_vu_ml
            + self.sp_vu_ml
            + self.ep_vu_ml
            + self.ha_vu_ml
            + self.sv_vu0_ml
            + self.ev_vu0_ml
    }
}

// ---- vitals --------------------------------------------------------------------------------------------

/// What a monitor (and the trauma team) reads. Pressures from the proximal systemic arteries.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct Vitals {
    /// Mean arterial pressure, time average over the last completed beat (mmHg).
    pub map_mmhg: f64,
    /// Maximum arterial pressure over the last completed beat (mmHg).
    pub systolic_mmhg: f64,
    /// Minimum arterial pressure over the last completed beat (mmHg).
    pub diastolic_mmhg: f64,
    /// Heart rate from the current heart period, 60/T (beats/min).
    pub hr_bpm: f64,
    /// Left-ventricular output averaged over the last completed beat (L/min).
    pub cardiac_output_l_min: f64,
    /// Circulating volume, sum of all compartments (mL).
    pub blood_volume_ml: f64,
    /// Volume removed by `remove_volume` since t = 0 (mL).
    pub blood_lost_ml: f64,
    /// `blood_lost_ml` over the circulating volume at t = 0.
    pub blood_lost_fraction: f64,
    /// ATLS hemorrhagic shock class 1–4 (see `shock_class`).
    pub shock_class: u8,
    /// Hepatic arterial inflow to the organ averaged over the last completed beat (mL/min).
    pub hepatic_flow_ml_min: f64,
}

/// ATLS class of hemorrhagic shock from the fraction of blood volume lost (ATLS 10th ed.): I below 15 %,
/// II 15–30 %, III 30–40 %, IV above 40 %. The simulation knows the loss exactly, so the class is the loss
/// class; heart rate and pressure are reported beside it as the physiological signs, not mixed into it (the
/// ATLS heart-rate bands describe a typical patient and are known to overlap widely between classes,
/// Mutschler et al., Resuscitation 84:309, 2013).
pub fn shock_class(blood_lost_fraction: f64) -> u8 {
    if blood_lost_fraction < 0.15 {
        1
    } else if blood_lost_fraction < 0.30 {
        2
    } else if blood_lost_fraction <= 0.40 {
        3
    } else {
        4
    }
}

// ---- model ---------------------------------------------------------------------------------------------

/// Statistics of the beat in progress and of the last completed one.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
struct Beats {
    /// Start time of the beat in progress (s).
    start_s: f64,
    /// Running max / min of arterial pressure in the beat in progress (mmHg).
    p_max: f64,
    p_min: f64,
    /// Hepatic volume at the start of the beat in progress (mL).
    hep_at_start_ml: f64,
    /// Last completed beat.
    map: f64,
    sys: f64,
    dia: f64,
    co_ml_s: f64,
    hep_ml_s: f64,
    /// Number of completed beats since construction.
    count: u64,
}

/// Ring buffer of the efferent inputs [P̃, x] (baroreceptor filter output, hypotensive drive) sampled every
/// `HISTORY_DT_S`, for the effector delays.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
struct History {
    samples: Vec<[f64; 2]>,
    /// Index of the newest sample.
    head: usize,
    /// Time of the newest sample (s, model clock).
    last_t: f64,
}

impl History {
    fn new(len: usize, value: [f64; 2], t: f64) -> History {
        History { samples: vec![value; len.max(2)], head: 0, last_t: t }
    }

    /// Linear interpolation at time `t` (clamped to the stored window; later than the newest → newest).
    /// Never panics, even on a hand-edited keyframe (empty buffer → zeros, head out of range → wrapped).
    fn at(&self, t: f64) -> [f64; 2] {
        let n = self.samples.len();
        if n == 0 {
            return [0.0, 0.0];
        }
        let head = self.head % n;
        let lag = ((self.last_t - t) / HISTORY_DT_S).clamp(0.0, (n - 1) as f64);
        let k = lag.floor();
        let w = lag - k;
        let k = (k as usize).min(n - 1);
        let i0 = (head + n - k) % n;
        let i1 = (head + n - (k + 1).min(n - 1)) % n;
        let (a, b) = (self.samples[i0], self.samples[i1]);
        [a[0] * (1.0 - w) + b[0] * w, a[1] * (1.0 - w) + b[1] * w]
    }

    fn push(&mut self, value: [f64; 2], t: f64) {
        let n = self.samples.len();
        self.last_t = t;
        if n == 0 {
            return;
        }
        self.head = (self.head + 1) % n;
        self.samples[self.head] = value;
    }
}

/// Instantaneous quantities of one right-hand-side evaluation.
#[derive(Clone, Copy, Debug, Default)]
struct Aux {
    p_sa: f64,
    q_ha: f64,
    q_portal: f64,
    period: f64,
}

/// The circulation. All state is in the struct and serialisable, so a keyframe restores it bit for bit.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CardioModel {
    p: CardioParams,
    t: f64,
    y: Y,
    history: History,
    beats: Beats,
    blood_lost_ml: f64,
    initial_volume_ml: f64,
}

impl CardioModel {
    /// Builds the model at an approximate (not periodic) initial state; see `settle` for a settled heart.
    pub fn new(p: CardioParams) -> Result<CardioModel, CardioError> {
        p.validate()?;
        let mut y = [0.0; NS];
        // Initial guess of pressures (mmHg) and flows (mL/s) near rest; venous volumes absorb the rest so that
        // the compartments add up to the total blood volume.
        let p_sa = p.baro_pn_mmhg;
        let q = 90.0;
        y[LV] = 120.0;
        y[RV] = 150.0;
        y[SA] = p.sa_vu_ml + p.sa_c_ml_per_mmhg * p_sa;
        y[F_SA] = q;
        let p_per = p_sa - p.sa_r_mmhg_s_per_ml * q;
        y[PER] = p.sp_vu_ml + p.ep_vu_ml + (p.sp_c_ml_per_mmhg + p.ep_c_ml_per_mmhg) * p_per;
        y[HA] = p.ha_vu_ml + p.ha_c_ml_per_mmhg * (p_sa - 2.0);
        y[RA] = p.ra_vu_ml + p.ra_c_ml_per_mmhg * 3.0;
        y[PA] = p.pa_vu_ml + p.pa_c_ml_per_mmhg * 16.0;
        y[F_PA] = q;
        y[PP] = p.pp_vu_ml + p.pp_c_ml_per_mmhg * 13.0;
        y[PV] = p.pv_vu_ml + p.pv_c_ml_per_mmhg * 8.0;
        y[LA] = p.la_vu_ml + p.la_c_ml_per_mmhg * 7.0;
        y[PTILDE] = p_sa;
        y[ISC] = isc_drive(&p, p_sa);
        // Effectors at the steady state of the initial carotid pressure.
        let (fes, fev) = efferent(&p, afferent(&p, p_sa), y[ISC]);
        let sig = sigmas(&p, fes, fev);
        for (k, s) in sig.iter().enumerate() {
            y[EFF + k] = *s;
        }
        let vu_sv = p.sv_vu0_ml + y[EFF + eff::VU_SV];
        let vu_ev = p.ev_vu0_ml + y[EFF + eff::VU_EV];
        let others: f64 = [LV, RV, SA, PER, HA, RA, PA, PP, PV, LA].iter().map(|&i| y[i]).sum();
        // Common venous pressure that makes the total right; splanchnic a little above extrasplanchnic.
        let c_ven = p.sv_c_ml_per_mmhg + p.ev_c_ml_per_mmhg;
        let p_ven = (p.total_blood_volume_ml - others - vu_sv - vu_ev) / c_ven;
        y[SV] = vu_sv + p.sv_c_ml_per_mmhg * p_ven;
        y[EV] = vu_ev + p.ev_c_ml_per_mmhg * p_ven;
        let hist_len = (max_delay(&p) / HISTORY_DT_S).ceil() as usize + 3;
        let mut m = CardioModel {
            history: History::new(hist_len, [p_sa, y[ISC]], 0.0),
            beats: Beats {
                start_s: 0.0,
                p_max: p_sa,
                p_min: p_sa,
                hep_at_start_ml: 0.0,
                map: p_sa,
                sys: p_sa,
                dia: p_sa,
                co_ml_s: q,
                hep_ml_s: 0.0,
                count: 0,
            },
            p,
            t: 0.0,
            y,
            blood_lost_ml: 0.0,
            initial_volume_ml: 0.0,
        };
        m.initial_volume_ml = m.circulating_volume_ml();
        let aux = m.aux();
        m.beats.hep_ml_s = aux.q_ha;
        Ok(m)
    }

    /// Builds the model and runs it `p.settle_s` seconds to a periodic steady state, then restarts the clock,
    /// the hepatic volume and the blood-loss count at zero (the reflex delay history and the last-beat
    /// statistics are kept, so the vitals are valid at once).
    pub fn settle(p: CardioParams) -> Result<CardioModel, CardioError> {
        let mut m = CardioModel::new(p)?;
        let ts = m.p.settle_s;
        m.advance_to(ts);
        let t = m.t;
        m.t = 0.0;
        m.history.last_t -= t;
        m.beats.start_s -= t;
        m.beats.hep_at_start_ml -= m.y[HEP_VOL];
        m.y[HEP_VOL] = 0.0;
        m.blood_lost_ml = 0.0;
        m.initial_volume_ml = m.circulating_volume_ml();
        Ok(m)
    }

    /// The parameters the model runs with.
    pub fn params(&self) -> &CardioParams {
        &self.p
    }

    /// Model time (s).
    pub fn time(&self) -> f64 {
        self.t
    }

    /// Integrates up to time `t` with fixed RK4 steps of `dt_s` and a shorter last step that ends on `t`.
    /// No-op if `t <= time()` (or `t` is not finite).
    pub fn advance_to(&mut self, t: f64) {
        if !t.is_finite() {
            return;
        }
        let dt = self.p.dt_s;
        while self.t < t {
            let h = (t - self.t).min(dt);
            self.step(h);
            self.t = if h < dt { t } else { self.t + h };
        }
    }

    /// Hemorrhage: removes `volume_m3` of blood, from the splanchnic veins (the liver's venous side, the wound's
    /// source) and, if they would be emptied, from the other compartments in turn, so that no compartment's
    /// volume goes negative. Non-finite or non-positive requests are ignored. What was actually removed is
    /// added to `blood_lost_ml`.
    pub fn remove_volume(&mut self, volume_m3: f64) {
        if !(volume_m3.is_finite() && volume_m3 > 0.0) {
            return;
        }
        let mut left = volume_m3 * ML_PER_M3;
        for i in [SV, EV, RA, PER, PV, PP, LA, PA, SA, HA, LV, RV] {
            let take = left.min(self.y[i].max(0.0));
            self.y[i] -= take;
            self.blood_lost_ml += take;
            left -= take;
            if left <= 0.0 {
                break;
            }
        }
    }

    /// Instantaneous hepatic arterial inflow to the organ (m³/s), ≥ 0.
    pub fn hepatic_flow_m3_s(&self) -> f64 {
        self.aux().q_ha.max(0.0) / ML_PER_M3
    }

    /// Instantaneous portal venous inflow to the liver (m³/s): the flow through the rest of the splanchnic bed
    /// (gut, spleen), all of which reaches the liver through the portal vein.
    pub fn portal_flow_m3_s(&self) -> f64 {
        self.aux().q_portal.max(0.0) / ML_PER_M3
    }

    /// Time integral of the hepatic arterial inflow since t = 0 (m³), integrated by the ODE steps.
    pub fn hepatic_volume_m3(&self) -> f64 {
        self.y[HEP_VOL] / ML_PER_M3
    }

    /// Circulating blood volume: sum of all compartments (m³).
    pub fn circulating_volume_m3(&self) -> f64 {
        self.circulating_volume_ml() / ML_PER_M3
    }

    fn circulating_volume_ml(&self) -> f64 {
        VOLUMES.iter().map(|&i| self.y[i]).sum()
    }

    /// Instantaneous proximal arterial pressure (mmHg).
    pub fn arterial_pressure_mmhg(&self) -> f64 {
        self.aux().p_sa
    }

    /// Current vital signs.
    pub fn vitals(&self) -> Vitals {
        let b = &self.beats;
        let frac = self.blood_lost_ml / self.initial_volume_ml;
        Vitals {
            map_mmhg: b.map,
            systolic_mmhg: b.sys,
            diastolic_mmhg: b.dia,
            hr_bpm: 60.0 / self.aux().period,
            cardiac_output_l_min: b.co_ml_s * 0.06,
            blood_volume_ml: self.circulating_volume_ml(),
            blood_lost_ml: self.blood_lost_ml,
            blood_lost_fraction: frac,
            shock_class: shock_class(frac),
            hepatic_flow_ml_min: b.hep_ml_s * 60.0,
        }
    }

    fn aux(&self) -> Aux {
        let mut d = [0.0; NS];
        self.rhs(self.t, &self.y, &mut d)
    }

    /// One RK4 step of length `h`, then the beat bookkeeping and the delay history.
    fn step(&mut self, h: f64) {
        let y0 = self.y;
        let t0 = self.t;
        let mut k1 = [0.0; NS];
        let mut k2 = [0.0; NS];
        let mut k3 = [0.0; NS];
        let mut k4 = [0.0; NS];
        let mut yt = [0.0; NS];
        self.rhs(t0, &y0, &mut k1);
        for i in 0..NS {
            yt[i] = y0[i] + 0.5 * h * k1[i];
        }
        self.rhs(t0 + 0.5 * h, &yt, &mut k2);
        for i in 0..NS {
            yt[i] = y0[i] + 0.5 * h * k2[i];
        }
        self.rhs(t0 + 0.5 * h, &yt, &mut k3);
        for i in 0..NS {
            yt[i] = y0[i] + h * k3[i];
        }
        self.rhs(t0 + h, &yt, &mut k4);
        for i in 0..NS {
            self.y[i] = y0[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        let t1 = t0 + h;
        // Delay history.
        while self.history.last_t + HISTORY_DT_S <= t1 + 1e-12 {
            // Sample P̃ at the grid time by linear interpolation across the step.
            let ts = self.history.last_t + HISTORY_DT_S;
            let w = ((ts - t0) / h).clamp(0.0, 1.0);
            let v = [y0[PTILDE] * (1.0 - w) + self.y[PTILDE] * w, y0[ISC] * (1.0 - w) + self.y[ISC] * w];
            self.history.push(v, ts);
        }
        // Beat statistics.
        let p_sa = (self.y[SA] - self.p.sa_vu_ml) / self.p.sa_c_ml_per_mmhg;
        self.beats.p_max = self.beats.p_max.max(p_sa);
        self.beats.p_min = self.beats.p_min.min(p_sa);
        if self.y[PHASE] >= 1.0 {
            self.y[PHASE] -= self.y[PHASE].floor();
            let dur = t1 - self.beats.start_s;
            if dur > 0.0 {
                let b = &mut self.beats;
                b.map = self.y[BEAT_P] / dur;
                b.co_ml_s = self.y[BEAT_EJ] / dur;
                b.hep_ml_s = (self.y[HEP_VOL] - b.hep_at_start_ml) / dur;
                b.sys = b.p_max;
                b.dia = b.p_min;
                b.count += 1;
            }
            let b = &mut self.beats;
            b.start_s = t1;
            b.p_max = p_sa;
            b.p_min = p_sa;
            b.hep_at_start_ml = self.y[HEP_VOL];
            self.y[BEAT_P] = 0.0;
            self.y[BEAT_EJ] = 0.0;
        }
    }

    /// Right-hand side dy/dt at time `t`; returns instantaneous auxiliaries.
    fn rhs(&self, t: f64, y: &Y, d: &mut Y) -> Aux {
        let p = &self.p;
        // Effector outputs.
        let emax_lv = p.lv_emax0_mmhg_per_ml + y[EFF + eff::EMAX_LV];
        let emax_rv = p.rv_emax0_mmhg_per_ml + y[EFF + eff::EMAX_RV];
        let r_sp = p.sp_r0_mmhg_s_per_ml + y[EFF + eff::R_SP];
        let r_ep = p.ep_r0_mmhg_s_per_ml + y[EFF + eff::R_EP];
        let vu_sv = p.sv_vu0_ml + y[EFF + eff::VU_SV];
        let vu_ev = p.ev_vu0_ml + y[EFF + eff::VU_EV];
        // Period floor 0.25 s (240 bpm) only guards against absurd parameter sets.
        let period = (p.heart_period0_s + y[EFF + eff::T_S] + y[EFF + eff::T_V]).max(0.25);

        // Pressures.
        let p_sa = (y[SA] - p.sa_vu_ml) / p.sa_c_ml_per_mmhg;
        let p_per = (y[PER] - p.sp_vu_ml - p.ep_vu_ml) / (p.sp_c_ml_per_mmhg + p.ep_c_ml_per_mmhg);
        let p_ha = (y[HA] - p.ha_vu_ml) / p.ha_c_ml_per_mmhg;
        let p_sv = (y[SV] - vu_sv) / p.sv_c_ml_per_mmhg;
        let p_ev = (y[EV] - vu_ev) / p.ev_c_ml_per_mmhg;
        let p_ra = (y[RA] - p.ra_vu_ml) / p.ra_c_ml_per_mmhg;
        let p_pa = (y[PA] - p.pa_vu_ml) / p.pa_c_ml_per_mmhg;
        let p_pp = (y[PP] - p.pp_vu_ml) / p.pp_c_ml_per_mmhg;
        let p_pv = (y[PV] - p.pv_vu_ml) / p.pv_c_ml_per_mmhg;
        let p_la = (y[LA] - p.la_vu_ml) / p.la_c_ml_per_mmhg;

        // Ventricles.
        let u = y[PHASE] - y[PHASE].floor();
        let tsys = (p.systole0_s - p.systole_k_s2 / period).clamp(0.05, 0.9 * period);
        let ts = u * period;
        let act = if ts < tsys {
            let s = (std::f64::consts::PI * ts / tsys).sin();
            s * s
        } else {
            0.0
        };
        let (q_ao, q_mi) = ventricle(
            act,
            y[LV],
            emax_lv,
            p.lv_vu_ml,
            p.lv_p0_mmhg,
            p.lv_ke_per_ml,
            p.lv_kr_s_per_ml,
            p_sa,
            p_la,
            p.la_r_mmhg_s_per_ml,
        );
        let (q_pu, q_tr) = ventricle(
            act,
            y[RV],
            emax_rv,
            p.rv_vu_ml,
            p.rv_p0_mmhg,
            p.rv_ke_per_ml,
            p.rv_kr_s_per_ml,
            p_pa,
            p_ra,
            p.ra_r_mmhg_s_per_ml,
        );

        let (q_ao, q_mi) = (q_ao * gate(y[LV]), q_mi * gate(y[LA]));
        let (q_pu, q_tr) = (q_pu * gate(y[RV]), q_tr * gate(y[RA]));

        // Systemic flows.
        let f = p.hepatic_conductance_fraction;
        let q_ha = gated((p_sa - p_ha) / p.ha_conduit_r_mmhg_s_per_ml, y[SA], y[HA]);
        let q_hep_bed = gated((p_ha - p_sv) * f / r_sp, y[HA], y[SV]);
        let q_portal = gated((p_per - p_sv) * (1.0 - f) / r_sp, y[PER], y[SV]);
        let q_ep = gated((p_per - p_ev) / r_ep, y[PER], y[EV]);
        let q_sv = gated((p_sv - p_ra) / p.sv_r_mmhg_s_per_ml, y[SV], y[RA]);
        let q_ev = gated((p_ev - p_ra) / p.ev_r_mmhg_s_per_ml, y[EV], y[RA]);
        let q_sa = gated(y[F_SA], y[SA], y[PER]);
        // Pulmonary flows.
        let q_pa = gated(y[F_PA], y[PA], y[PP]);
        let q_pp = gated((p_pp - p_pv) / p.pp_r_mmhg_s_per_ml, y[PP], y[PV]);
        let q_pv = gated((p_pv - p_la) / p.pv_r_mmhg_s_per_ml, y[PV], y[LA]);

        d[LV] = q_mi - q_ao;
        d[SA] = q_ao - q_sa - q_ha;
        d[F_SA] = (p_sa - p_per - p.sa_r_mmhg_s_per_ml * y[F_SA]) / p.sa_l_mmhg_s2_per_ml;
        d[PER] = q_sa - q_portal - q_ep;
        d[HA] = q_ha - q_hep_bed;
        d[SV] = q_portal + q_hep_bed - q_sv;
        d[EV] = q_ep - q_ev;
        d[RA] = q_sv + q_ev - q_tr;
        d[RV] = q_tr - q_pu;
        d[PA] = q_pu - q_pa;
        d[F_PA] = (p_pa - p_pp - p.pa_r_mmhg_s_per_ml * y[F_PA]) / p.pa_l_mmhg_s2_per_ml;
        d[PP] = q_pa - q_pp;
        d[PV] = q_pp - q_pv;
        d[LA] = q_pv - q_mi;
        d[PHASE] = 1.0 / period;

        // Baroreceptor filter: τp dP̃/dt = Pcs + τz dPcs/dt − P̃, Pcs = Psa.
        let dp_sa = d[SA] / p.sa_c_ml_per_mmhg;
        d[PTILDE] = (p_sa + p.baro_tau_z_s * dp_sa - y[PTILDE]) / p.baro_tau_p_s;
        d[ISC] = (isc_drive(p, p_sa) - y[ISC]) / p.isc_tau_s;

        // Effectors driven by the delayed efferent activity.
        let taus = [
            (p.eff_emax_lv_tau_s, p.eff_emax_lv_delay_s),
            (p.eff_emax_rv_tau_s, p.eff_emax_rv_delay_s),
            (p.eff_r_sp_tau_s, p.eff_r_sp_delay_s),
            (p.eff_r_ep_tau_s, p.eff_r_ep_delay_s),
            (p.eff_vu_sv_tau_s, p.eff_vu_sv_delay_s),
            (p.eff_vu_ev_tau_s, p.eff_vu_ev_delay_s),
            (p.eff_t_s_tau_s, p.eff_t_s_delay_s),
            (p.eff_t_v_tau_s, p.eff_t_v_delay_s),
        ];
        let mut cache = (f64::NAN, [0.0; 8]);
        for (k, (tau, delay)) in taus.iter().enumerate() {
            if *delay != cache.0 {
                let [pt, x] = self.history.at(t - delay);
                let (fes, fev) = efferent(p, afferent(p, pt), x);
                cache = (*delay, sigmas(p, fes, fev));
            }
            d[EFF + k] = (cache.1[k] - y[EFF + k]) / tau;
        }

        d[HEP_VOL] = q_ha;
        d[BEAT_P] = p_sa;
        d[BEAT_EJ] = q_ao;
        Aux { p_sa, q_ha, q_portal, period }
    }
}

/// Volume below which a compartment's outflows are scaled down linearly to zero (mL). The linear P–V laws
/// of the model allow negative volumes once pressures go far below zero (exsanguination beyond ≈ 55 % of
/// blood volume, when reverse flows suck a collapsed compartment dry); real vessels collapse instead. Every
/// compartment holds far more than this in any survivable state (the smallest, the hepatic artery, ≈ 0.7 mL
/// at rest), so the gate changes nothing there; it conserves volume since the same flow leaves and enters.
const V_COLLAPSE_ML: f64 = 0.1;

/// Outflow gate of a compartment holding `v` mL.
fn gate(v: f64) -> f64 {
    (v / V_COLLAPSE_ML).clamp(0.0, 1.0)
}

/// Flow `q` from compartment a (volume `va`) to b (volume `vb`), gated by the volume of whichever is its source.
fn gated(q: f64, va: f64, vb: f64) -> f64 {
    if q >= 0.0 { q * gate(va) } else { q * gate(vb) }
}

/// Ventricle with its inflow and outflow valves (Ursino 1998): returns (outflow, inflow) in mL/s.
/// `p_out`/`p_in` are the pressures downstream of the outflow valve and upstream of the inflow valve.
#[allow(clippy::too_many_arguments)]
fn ventricle(
    act: f64,
    v: f64,
    emax: f64,
    vu: f64,
    p0: f64,
    ke: f64,
    kr: f64,
    p_out: f64,
    p_in: f64,
    r_in: f64,
) -> (f64, f64) {
    let p_max = act * emax * (v - vu) + (1.0 - act) * p0 * ((ke * v).exp() - 1.0);
    let r = (kr * p_max).max(1.0e-6);
    let q_out = if p_max > p_out { (p_max - p_out) / r } else { 0.0 };
    let p_v = p_max - r * q_out;
    let q_in = if p_in > p_v { (p_in - p_v) / r_in } else { 0.0 };
    (q_out, q_in)
}

/// Afferent carotid firing (spikes/s) from the filtered carotid pressure P̃.
fn afferent(p: &CardioParams, p_tilde: f64) -> f64 {
    let x = ((p_tilde - p.baro_pn_mmhg) / p.baro_ka_mmhg).clamp(-50.0, 50.0);
    let e = x.exp();
    (p.baro_fmin_hz + p.baro_fmax_hz * e) / (1.0 + e)
}

/// (sympathetic, vagal) efferent firing (spikes/s) from the afferent firing `fcs` and the hypotensive drive
/// `x`: Ursino 1998 eqs. with `x` as an extra excitatory input in the sympathetic exponent and a vagal
/// withdrawal, as the chemoreceptor/CNS inputs of Ursino & Magosso (2000).
fn efferent(p: &CardioParams, fcs: f64, x: f64) -> (f64, f64) {
    let fes = p.symp_finf_hz + (p.symp_f0_hz - p.symp_finf_hz) * (-p.symp_k_s * (fcs - x)).exp();
    let fes = fes.min(p.symp_fmax_hz);
    let z = ((fcs - p.vagal_fcs0_hz) / p.vagal_k_hz).clamp(-50.0, 50.0);
    let e = z.exp();
    let fev = (p.vagal_f0_hz + p.vagal_finf_hz * e) / (1.0 + e);
    (fes, (fev - p.isc_vagal_weight * x).max(0.0))
}

/// Static hypotensive sympathetic drive (spikes/s) at arterial pressure `p_a`: a falling sigmoid.
fn isc_drive(p: &CardioParams, p_a: f64) -> f64 {
    let z = ((p_a - p.isc_p50_mmhg) / p.isc_k_mmhg).clamp(-50.0, 50.0);
    p.isc_gain_hz / (1.0 + z.exp())
}

/// Static effector targets σθ (Ursino 1998): logarithmic in the sympathetic activity above threshold, linear
/// in the vagal activity for the vagal heart-period term.
fn sigmas(p: &CardioParams, fes: f64, fev: f64) -> [f64; 8] {
    let ls = if fes >= p.symp_fmin_hz { (fes - p.symp_fmin_hz + 1.0).ln() } else { 0.0 };
    [
        p.eff_emax_lv_gain * ls,
        p.eff_emax_rv_gain * ls,
        p.eff_r_sp_gain * ls,
        p.eff_r_ep_gain * ls,
        p.eff_vu_sv_gain * ls,
        p.eff_vu_ev_gain * ls,
        p.eff_t_s_gain * ls,
        p.eff_t_v_gain * fev,
    ]
}

fn max_delay(p: &CardioParams) -> f64 {
    p.effector_fields().iter().map(|e| e.3).fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::OnceLock;

    /// The default model settled once (60 s of simulated time) and shared by the tests.
    fn settled() -> CardioModel {
        static M: OnceLock<CardioModel> = OnceLock::new();
        M.get_or_init(|| CardioModel::settle(CardioParams::default()).expect("default parameters are valid")).clone()
    }

    /// Samples the hepatic inflow (mL/s) every `dt` over `dur` seconds: (max, min).
    fn hepatic_extremes(m: &mut CardioModel, dur: f64, dt: f64) -> (f64, f64) {
        let (mut mx, mut mn) = (f64::MIN, f64::MAX);
        let t0 = m.time();
        let n = (dur / dt).round() as usize;
        for i in 1..=n {
            m.advance_to(t0 + i as f64 * dt);
            let q = m.hepatic_flow_m3_s() * ML_PER_M3;
            mx = mx.max(q);
            mn = mn.min(q);
        }
        (mx, mn)
    }

    #[test]
    fn baseline_vitals_are_physiological() {
        let mut m = settled();
        let v = m.vitals();
        let share = v.hepatic_flow_ml_min / (v.cardiac_output_l_min * 1000.0);
        let period = 60.0 / v.hr_bpm;
        let (mx, mn) = hepatic_extremes(&mut m, 2.0 * period, 5.0e-4);
        println!(
            "baseline: MAP {:.1} mmHg, {:.1}/{:.1} mmHg, HR {:.1} bpm, CO {:.2} L/min, hepatic {:.0} mL/min = {:.1} % \
             of CO, hepatic inflow {:.1}..{:.1} mL/s (max/min {:.2}, RI {:.2})",
            v.map_mmhg,
            v.systolic_mmhg,
            v.diastolic_mmhg,
            v.hr_bpm,
            v.cardiac_output_l_min,
            v.hepatic_flow_ml_min,
            100.0 * share,
            mn,
            mx,
            mx / mn,
            (mx - mn) / mx
        );
        assert!((85.0..=100.0).contains(&v.map_mmhg), "MAP {}", v.map_mmhg);
        assert!((65.0..=80.0).contains(&v.hr_bpm), "HR {}", v.hr_bpm);
        assert!((4.5..=6.0).contains(&v.cardiac_output_l_min), "CO {}", v.cardiac_output_l_min);
        assert!((110.0..=130.0).contains(&v.systolic_mmhg), "systolic {}", v.systolic_mmhg);
        assert!((65.0..=85.0).contains(&v.diastolic_mmhg), "diastolic {}", v.diastolic_mmhg);
        assert!((300.0..=450.0).contains(&v.hepatic_flow_ml_min), "hepatic {}", v.hepatic_flow_ml_min);
        assert!((0.05..=0.10).contains(&share), "hepatic share of CO {share}");
        assert!(mn > 0.0 && mx / mn > 1.5, "hepatic inflow not pulsatile: {mn}..{mx}");
        assert_eq!(v.shock_class, 1);
        assert_eq!(v.blood_lost_ml, 0.0);
        assert!((v.blood_volume_ml - 5000.0).abs() < 1e-6);
        // Portal inflow ≈ 3× arterial: the hepatic artery is ≈ 25 % of liver flow.
        let portal = m.portal_flow_m3_s() * ML_PER_M3 * 60.0;
        println!("portal inflow (instantaneous) {portal:.0} mL/min");
        assert!((600.0..=1500.0).contains(&portal), "portal {portal} mL/min");
    }

    #[test]
    fn closed_loop_conserves_volume_without_a_wound() {
        // From the unsettled initial state too, where the reflexes move unstressed volumes the most.
        for mut m in [CardioModel::new(CardioParams::default()).expect("valid"), settled()] {
            let v0 = m.circulating_volume_m3();
            let mut worst = 0.0f64;
            for _ in 0..60 {
                m.advance_to(m.time() + 1.0);
                worst = worst.max(((m.circulating_volume_m3() - v0) / v0).abs());
            }
            println!("volume drift over 60 s: {worst:e} relative");
            assert!(worst < 1e-9, "relative drift {worst}");
            assert_eq!(m.vitals().blood_lost_ml, 0.0);
        }
    }

    #[test]
    fn hepatic_volume_is_the_integral_of_hepatic_flow() {
        let mut m = settled();
        let period = 60.0 / m.vitals().hr_bpm;
        let t0 = m.time();
        let v0 = m.hepatic_volume_m3();
        let dt = 2.5e-4;
        let n = (5.0 * period / dt).round() as usize;
        let mut q_prev = m.hepatic_flow_m3_s();
        let mut trap = 0.0;
        for i in 1..=n {
            m.advance_to(t0 + i as f64 * dt);
            let q = m.hepatic_flow_m3_s();
            trap += 0.5 * (q + q_prev) * dt;
            q_prev = q;
        }
        let integ = m.hepatic_volume_m3() - v0;
        let rel = (integ - trap).abs() / trap;
        println!("5 beats: ODE {:.4} mL, trapezoid {:.4} mL, rel diff {rel:e}", integ * 1e6, trap * 1e6);
        assert!(rel < 0.005, "relative difference {rel}");
        // Since t = 0 of a settled model: positive and ≈ mean flow × time.
        assert!(m.hepatic_volume_m3() > 0.0);
    }

    /// Bleeds `fraction` of the blood volume at a constant rate over `dur` seconds in 10 ms chunks (as the
    /// SPH coupling does), then waits `after` seconds. Returns per-minute vitals and the final ones.
    fn bleed(fraction: f64, dur: f64, after: f64) -> (Vitals, Vec<Vitals>, Vitals, Option<f64>) {
        let mut m = settled();
        let base = m.vitals();
        let rate = fraction * m.circulating_volume_m3() / dur;
        let chunk = 0.01;
        let mut per_minute = Vec::new();
        let mut hr120_at = None;
        let n = (dur / chunk).round() as usize;
        for i in 1..=n {
            m.advance_to(i as f64 * chunk);
            m.remove_volume(rate * chunk);
            if i % 6000 == 0 {
                per_minute.push(m.vitals());
            }
            if hr120_at.is_none() && m.vitals().hr_bpm > 120.0 {
                hr120_at = Some(m.time());
            }
        }
        m.advance_to(dur + after);
        (base, per_minute, m.vitals(), hr120_at)
    }

    #[test]
    fn hemorrhage_of_35_percent_reaches_atls_class_3() {
        let (base, mins, end, hr120_at) = bleed(0.35, 600.0, 0.0);
        for (k, v) in mins.iter().enumerate() {
            println!(
                "minute {:2}: lost {:4.1} %, MAP {:5.1}, {:5.1}/{:4.1} mmHg, HR {:5.1}, CO {:4.2}, hepatic {:4.0} mL/min, class {}",
                k + 1,
                100.0 * v.blood_lost_fraction,
                v.map_mmhg,
                v.systolic_mmhg,
                v.diastolic_mmhg,
                v.hr_bpm,
                v.cardiac_output_l_min,
                v.hepatic_flow_ml_min,
                v.shock_class
            );
        }
        println!("HR first above 120 bpm at t = {hr120_at:?} s");
        assert!((end.blood_lost_fraction - 0.35).abs() < 1e-6, "lost {}", end.blood_lost_fraction);
        assert_eq!(end.shock_class, 3);
        assert!(end.hr_bpm > 120.0, "HR {}", end.hr_bpm);
        assert!(end.systolic_mmhg < base.systolic_mmhg - 20.0, "systolic {}", end.systolic_mmhg);
        // Systolic pressure falls minute by minute while bleeding.
        for w in mins.windows(2) {
            assert!(w[1].systolic_mmhg < w[0].systolic_mmhg, "{} then {}", w[0].systolic_mmhg, w[1].systolic_mmhg);
        }
        assert!(mins[0].systolic_mmhg < base.systolic_mmhg);
        // Loss is bookkept both ways.
        assert!((end.blood_volume_ml + end.blood_lost_ml - 5000.0).abs() < 1e-6);
        assert!(end.hepatic_flow_ml_min < base.hepatic_flow_ml_min);
    }

    #[test]
    fn hemorrhage_of_10_percent_is_class_1_with_modest_tachycardia() {
        let (base, _, end, _) = bleed(0.10, 120.0, 60.0);
        println!(
            "10 %: HR {:.1} → {:.1} bpm, MAP {:.1} → {:.1} mmHg, systolic {:.1} → {:.1}",
            base.hr_bpm, end.hr_bpm, base.map_mmhg, end.map_mmhg, base.systolic_mmhg, end.systolic_mmhg
        );
        assert_eq!(end.shock_class, 1);
        assert!(end.hr_bpm > base.hr_bpm && end.hr_bpm - base.hr_bpm < 15.0, "HR {} → {}", base.hr_bpm, end.hr_bpm);
        assert!(end.map_mmhg > 75.0, "MAP {}", end.map_mmhg);
    }

    #[test]
    fn exsanguination_stays_finite_and_never_empties_a_compartment_below_zero() {
        let mut m = settled();
        m.advance_to(1.0);
        m.remove_volume(0.0035); // 3.5 L at once: more than the splanchnic veins hold
        m.remove_volume(f64::NAN);
        m.remove_volume(-1.0);
        for &i in &VOLUMES {
            assert!(m.y[i] >= 0.0, "compartment {i}: {}", m.y[i]);
        }
        m.advance_to(30.0);
        for &i in &VOLUMES {
            assert!(m.y[i] >= -1e-9, "compartment {i}: {}", m.y[i]);
        }
        let v = m.vitals();
        assert!(v.map_mmhg.is_finite() && v.hr_bpm.is_finite() && v.cardiac_output_l_min.is_finite());
        assert_eq!(v.shock_class, 4);
        assert!((v.blood_lost_ml - 3500.0).abs() < 1e-6, "lost {}", v.blood_lost_ml);
        // Asking for more than is there removes what is there.
        m.remove_volume(1.0);
        assert!(m.circulating_volume_m3().abs() < 1e-9, "left {}", m.circulating_volume_m3());
        assert!((m.vitals().blood_lost_ml - 5000.0).abs() < 1e-3);
        m.advance_to(31.0);
        assert!(m.vitals().map_mmhg.is_finite());
    }

    #[test]
    fn shock_class_bands() {
        assert_eq!(shock_class(0.0), 1);
        assert_eq!(shock_class(0.149), 1);
        assert_eq!(shock_class(0.15), 2);
        assert_eq!(shock_class(0.299), 2);
        assert_eq!(shock_class(0.30), 3);
        assert_eq!(shock_class(0.40), 3);
        assert_eq!(shock_class(0.401), 4);
    }

    #[test]
    fn invalid_parameters_name_the_field() {
        let p = CardioParams { sa_c_ml_per_mmhg: f64::NAN, ..CardioParams::default() };
        let e = p.validate().expect_err("NaN accepted").to_string();
        assert!(e.starts_with("cardio.sa_c_ml_per_mmhg = NaN"), "{e}");
        let p = CardioParams { heart_period0_s: -3.0, ..CardioParams::default() };
        let e = CardioModel::new(p).expect_err("negative accepted").to_string();
        assert!(e.contains("cardio.heart_period0_s = -3: must be in 0.24..3"), "{e}");
        let p = CardioParams { eff_t_v_delay_s: -0.1, ..CardioParams::default() };
        assert!(p.validate().expect_err("negative delay").to_string().contains("eff_t_v_delay_s"));
        let p = CardioParams { isc_gain_hz: f64::INFINITY, ..CardioParams::default() };
        assert!(p.validate().expect_err("inf").to_string().contains("cardio.isc_gain_hz = inf: is not a finite"));
        let p = CardioParams { total_blood_volume_ml: 3000.0, ..CardioParams::default() };
        let e = p.validate().expect_err("volume below unstressed").to_string();
        assert!(e.contains("cardio.total_blood_volume_ml = 3000") && e.contains("unstressed"), "{e}");
        assert!(CardioParams::default().validate().is_ok());
    }

    #[test]
    fn params_deserialize_with_defaults_and_reject_unknown_fields() {
        let p: CardioParams = serde_json::from_str(r#"{"total_blood_volume_ml": 5200}"#).expect("partial params");
        assert_eq!(p.total_blood_volume_ml, 5200.0);
        assert_eq!(p.sa_c_ml_per_mmhg, CardioParams::default().sa_c_ml_per_mmhg);
        let e = serde_json::from_str::<CardioParams>(r#"{"heart_rate": 70}"#).expect_err("unknown field");
        assert!(e.to_string().contains("heart_rate"), "{e}");
    }

    /// Every float in a JSON value.
    fn floats(v: &serde_json::Value, out: &mut Vec<f64>) {
        match v {
            serde_json::Value::Number(n) => out.extend(n.as_f64()),
            serde_json::Value::Array(a) => a.iter().for_each(|x| floats(x, out)),
            serde_json::Value::Object(o) => o.values().for_each(|x| floats(x, out)),
            _ => {}
        }
    }

    #[test]
    fn serde_round_trip_continues_bit_identically() {
        let mut a = settled();
        a.advance_to(3.217); // mid-beat, mid history interval
        a.remove_volume(2.0e-5);
        // Through the serde data model (serde_json::Value keeps f64 exactly): always bit-identical.
        let value = serde_json::to_value(&a).expect("to value");
        let mut b: CardioModel = serde_json::from_value(value.clone()).expect("from value");
        // Through JSON text: bit-identical only if serde_json parses floats exactly, which needs its
        // `float_roundtrip` feature (its default parser is best-effort, 1 ulp off now and then).
        let text = serde_json::to_string(&a).expect("serialise");
        let mut c: CardioModel = serde_json::from_str(&text).expect("deserialise");
        let mut all = Vec::new();
        floats(&value, &mut all);
        let text_exact = all.iter().all(|x| {
            serde_json::from_str::<f64>(&serde_json::to_string(x).expect("f64")).expect("f64").to_bits() == x.to_bits()
        });
        for m in [&mut a, &mut b, &mut c] {
            m.advance_to(5.0);
            m.remove_volume(1.0e-5);
            m.advance_to(9.123);
        }
        assert_eq!(a.vitals(), b.vitals());
        assert_eq!(a.hepatic_volume_m3().to_bits(), b.hepatic_volume_m3().to_bits());
        assert_eq!(a.hepatic_flow_m3_s().to_bits(), b.hepatic_flow_m3_s().to_bits());
        for i in 0..NS {
            assert_eq!(a.y[i].to_bits(), b.y[i].to_bits(), "state {i}");
        }
        assert_eq!(serde_json::to_value(&a).expect("a"), serde_json::to_value(&b).expect("b"));
        println!("keyframe JSON: {} bytes, {} floats, text parse exact: {text_exact}", text.len(), all.len());
        if text_exact {
            assert_eq!(a.vitals(), c.vitals());
            assert_eq!(serde_json::to_string(&a).expect("a"), serde_json::to_string(&c).expect("c"));
        } else {
            println!("serde_json without `float_roundtrip`: JSON text keyframes are not bit-exact");
            let (va, vc) = (a.vitals(), c.vitals());
            assert!((va.map_mmhg - vc.map_mmhg).abs() < 1e-9 && (va.hr_bpm - vc.hr_bpm).abs() < 1e-9);
        }
    }

    #[test]
    fn advance_to_is_independent_of_call_pattern_and_ignores_the_past() {
        let mut a = settled();
        let mut b = settled();
        a.advance_to(2.0);
        for k in 1..=200 {
            b.advance_to(k as f64 * 0.01);
        }
        let t = b.time();
        b.advance_to(1.0); // the past: no-op
        b.advance_to(f64::NAN);
        assert_eq!(b.time(), t);
        assert_eq!(a.time(), 2.0);
        // Steps of 0.01 s are whole multiples of dt = 2e-4 up to round-off: same trajectory to ~1e-9.
        let (va, vb) = (a.vitals(), b.vitals());
        assert!((va.map_mmhg - vb.map_mmhg).abs() < 1e-6 && (va.hr_bpm - vb.hr_bpm).abs() < 1e-6);
        assert!((a.hepatic_volume_m3() - b.hepatic_volume_m3()).abs() < 1e-12);
    }

    #[test]
    fn without_the_hypotensive_drive_the_baroreflex_saturates_below_class_3_tachycardia() {
        // Pure Ursino 1998 (documents why the extension exists): the carotid reflex alone cannot exceed
        // ≈ 108 bpm however low the pressure.
        let p = CardioParams { isc_gain_hz: 0.0, ..CardioParams::default() };
        let (fes, fev) = efferent(&p, p.baro_fmin_hz, 0.0);
        let s = sigmas(&p, fes, fev);
        let t_min = p.heart_period0_s + s[eff::T_S] + s[eff::T_V];
        println!("carotid-only ceiling: {:.1} bpm", 60.0 / t_min);
        assert!(60.0 / t_min < 120.0);
        let q = CardioParams::default();
        let (fes, fev) = efferent(&q, q.baro_fmin_hz, q.isc_gain_hz);
        let s = sigmas(&q, fes, fev);
        let t_min = q.heart_period0_s + s[eff::T_S] + s[eff::T_V];
        println!("with the hypotensive drive: {:.1} bpm, fes {fes:.1} spikes/s", 60.0 / t_min);
        assert!(60.0 / t_min > 120.0 && fes < q.symp_fmax_hz);
    }
}
