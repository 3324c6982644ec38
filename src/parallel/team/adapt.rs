//! The A/B rule of an `Auto` team (the parent module's docs): probe
//! windows with the helper and alone, and the stretches run the faster
//! way.

/// Passes ([`super::concurrent`] calls on the caller) in one probe window of an
/// `Auto` team.
pub(crate) const PROBE_PASSES: u32 = 24;
/// Windows an `Auto` team runs the way its last probe found faster (the
/// first time, and after a probe that changed its mind).
pub(crate) const EXPLOIT_MIN: u32 = 8;
/// The most windows between two probes (each probe that confirms the last
/// decision doubles the stretch up to this), unless the machine gives
/// evidence against the decision ([`DOUBT_WINDOWS`]).
pub(crate) const EXPLOIT_MAX: u32 = 128;
/// Windows in a row with evidence against the decision being run after
/// which an `Auto` team ends the stretch and probes at once: running with
/// the helper, a half taken back from a helper that was awake but had not
/// started it (not on a core: the machine is busy); running alone because
/// no core was free, or on a first choice of one thread, fewer runnable
/// tasks on the machine than cores (`/proc/loadavg`: a core is free now).
/// The probe still decides.
pub(crate) const DOUBT_WINDOWS: u32 = 2;
/// An `Auto` team runs with its helper only when its probe windows took at
/// most this fraction of the wall time of the windows alone (a tie goes
/// to one thread).
pub(crate) const TEAM_MARGIN: f64 = 0.97;

/// An `Auto` team whose probe windows with the helper took at most this
/// fraction of the wall time of its windows alone (a clear gain, beyond
/// the noise of a shared host) runs the longest stretch, [`EXPLOIT_MAX`]
/// windows, at once: each probe runs half its windows alone, so on a
/// machine with a core free a run where the team clearly pays makes one
/// probe per `EXPLOIT_MAX` windows; evidence against the team still
/// ends the stretch ([`DOUBT_WINDOWS`]), and a machine whose cores are
/// all busy skips the probes.
pub(crate) const CLEAR_MARGIN: f64 = 0.8;

/// The probe windows, in order: with the helper (`false`) or alone
/// (`true`).
const PROBE_ORDER: [bool; 4] = [false, true, true, false];

/// The A/B rule of an `Auto` team (module docs): which way the passes
/// run now, and the wall times that decide it. Touched by the caller only.
#[derive(Debug)]
pub(super) struct Adapt {
    /// Passes per window.
    pub(super) window: u32,
    /// Passes left in the current window.
    pub(super) left: u32,
    /// Index into [`PROBE_ORDER`], or 4 while exploiting a decision.
    pub(super) phase: usize,
    /// Whether the current window runs alone.
    pub(super) solo: bool,
    /// Start of the current window.
    pub(super) start: Option<std::time::Instant>,
    /// Summed wall time of the probe windows: [with the helper, alone].
    pub(super) probe: [std::time::Duration; 2],
    /// Windows of the next exploit stretch.
    pub(super) exploit: u32,
    /// The last decision (alone?), if any.
    pub(super) last: Option<bool>,
    /// Decisions for the team and for one thread so far.
    pub(super) decided: [u32; 2],
    /// Wall time of the last probe's windows with the helper over that
    /// of its windows alone.
    pub(super) last_ratio: Option<f64>,
    /// Windows in a row of the current stretch with evidence against it.
    pub(super) doubts: u32,
    /// Stretches ended early by [`DOUBT_WINDOWS`] such windows.
    pub(super) cut: u32,
    /// Whether a core found free is evidence against the current stretch
    /// alone: it runs alone because no core was free (at its probe, or at
    /// a probe skipped for it), or its probe chose one thread after one
    /// that chose the team or none (not confirmed).
    pub(super) busy: bool,
    /// Probes not run because no core was free (the first one at the
    /// team's start included).
    pub(super) skipped: u32,
}

impl Adapt {
    /// The rule of a team opened with a core free (`free`: it starts with
    /// a probe) or without (it starts with a stretch of [`EXPLOIT_MIN`]
    /// windows alone, the probe skipped).
    pub(super) fn new(window: u32, free: bool) -> Self {
        let window = window.max(1);
        let mut a = Self {
            window,
            left: window,
            phase: 0,
            solo: PROBE_ORDER[0],
            start: None,
            probe: [std::time::Duration::ZERO; 2],
            exploit: EXPLOIT_MIN,
            last: None,
            decided: [0; 2],
            last_ratio: None,
            doubts: 0,
            cut: 0,
            busy: false,
            skipped: 0,
        };
        if !free {
            a.phase = PROBE_ORDER.len();
            a.solo = true;
            a.left = EXPLOIT_MIN * window;
            a.busy = true;
            a.skipped = 1;
        }
        a
    }

    /// Whether the pass just counted by [`Self::pass`] was the last of a
    /// window of an exploit stretch (where [`Self::evidence`] is asked).
    pub(super) fn exploit_window_ended(&self) -> bool {
        self.phase == PROBE_ORDER.len() && self.left % self.window == 0 && self.left > 0
    }

    /// Evidence (or none) against the decision being run, from the window
    /// that just ended ([`DOUBT_WINDOWS`]); after enough windows in a row
    /// the stretch ends with this pass and the next pass starts a probe.
    /// Returns whether the helper should be woken now (the probe's first
    /// window runs with it).
    pub(super) fn evidence(&mut self, against: bool) -> bool {
        if !against {
            self.doubts = 0;
            return false;
        }
        self.doubts += 1;
        if self.doubts < DOUBT_WINDOWS || self.phase != PROBE_ORDER.len() {
            return false;
        }
        self.doubts = 0;
        self.cut += 1;
        self.left = 0;
        self.solo && !PROBE_ORDER[0]
    }

    /// Counts one pass at `now`; returns whether it runs alone and whether
    /// the helper should be woken now (the next window runs with it after
    /// one that ran alone). `free` tells whether a core is free now; it is
    /// asked only where the answer decides: at the end of a stretch alone
    /// (no core free: the probe is skipped and another stretch runs
    /// alone, twice as long up to [`EXPLOIT_MAX`]) and when a probe
    /// chooses one thread.
    pub(super) fn pass(
        &mut self,
        now: std::time::Instant,
        mut free: impl FnMut() -> bool,
    ) -> (bool, bool) {
        let start = *self.start.get_or_insert(now);
        if self.left > 0 {
            self.left -= 1;
            if self.left == 0 && self.phase == PROBE_ORDER.len() && self.solo && !free() {
                self.skipped += 1;
                self.busy = true;
                self.doubts = 0;
                self.exploit = (2 * self.exploit).min(EXPLOIT_MAX);
                self.left = self.exploit * self.window;
                return (true, false);
            }
            let wake = self.left == 0 && self.solo && !self.next_solo();
            return (self.solo, wake);
        }
        // the current window ended with the previous pass
        let dt = now.saturating_duration_since(start);
        self.start = Some(now);
        if self.phase < PROBE_ORDER.len() {
            self.probe[usize::from(self.solo)] += dt;
            self.phase += 1;
        } else {
            self.phase = 0;
        }
        if self.phase == PROBE_ORDER.len() {
            let [team, alone] = self.probe;
            let solo = team.as_secs_f64() > TEAM_MARGIN * alone.as_secs_f64();
            self.last_ratio = Some(team.as_secs_f64() / alone.as_secs_f64().max(1e-12));
            let confirmed = self.last == Some(solo);
            self.exploit = if confirmed {
                (2 * self.exploit).min(EXPLOIT_MAX)
            } else {
                EXPLOIT_MIN
            };
            if team.as_secs_f64() <= CLEAR_MARGIN * alone.as_secs_f64() {
                self.exploit = EXPLOIT_MAX;
            }
            self.last = Some(solo);
            self.doubts = 0;
            self.decided[usize::from(solo)] += 1;
            self.solo = solo;
            // a free core doubts a first choice of one thread (the probe
            // may have met a passing load), and one made with no core free
            self.busy = solo && (!confirmed || !free());
            self.left = self.exploit * self.window;
        } else {
            if self.phase == 0 {
                self.probe = [std::time::Duration::ZERO; 2];
            }
            self.solo = PROBE_ORDER[self.phase];
            self.left = self.window;
        }
        // this pass is the first of the new window
        self.left -= 1;
        let wake = self.left == 0 && self.solo && !self.next_solo();
        (self.solo, wake)
    }

    /// Whether the window after the current one starts alone (after the
    /// last probe window: not known yet, taken as with the helper).
    pub(super) fn next_solo(&self) -> bool {
        match self.phase {
            p if p + 1 < PROBE_ORDER.len() => PROBE_ORDER[p + 1],
            p if p + 1 == PROBE_ORDER.len() => false,
            _ => PROBE_ORDER[0],
        }
    }
}
