//! Contact events, observed at accepted steps: the rods' wall contacts
//! (the falling rod, or every `[rod]`/`[[rod]]` of a scenario: starts and
//! ends of corner–wall contacts and the peak normal force,
//! [`ContactMonitor`]), and every contact force element of a scenario's
//! `[[force]]`s (first contact, starts, ends and peak normal force per
//! element, [`ElementContacts`]).

use crate::builders::RodInfo;
use crate::forces::{CornerState, Wall};
use crate::simulation::Monitor;
use serde::Serialize;
use serde_json::{Map, Value};

/// One contact start or end.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ContactEvent {
    /// The rod (its scenario name; `rod` for [`ContactMonitor::new`]).
    pub rod: String,
    /// Time of the first accepted step at which the new state was seen \[s\].
    pub t: f64,
    /// `start` or `end`.
    pub kind: &'static str,
    /// Segment, 1-based from the bottom.
    pub segment: usize,
    /// Corner 0..4 in [`crate::forces::WallContact::corner_offset`] order.
    pub corner: usize,
    /// `left` (x = −d/2) or `right` (x = +d/2).
    pub wall: &'static str,
}

/// The largest normal force seen.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct PeakForce {
    /// The rod.
    pub rod: String,
    /// Normal force \[N\].
    pub force: f64,
    /// When \[s\].
    pub t: f64,
    /// Segment, 1-based.
    pub segment: usize,
    /// Corner.
    pub corner: usize,
}

/// A [`Monitor`] that turns corner states into contact events.
///
/// Contacts are sampled at accepted integration steps, so an event's time is
/// accurate to one step and a contact shorter than a step may be missed.
#[derive(Debug)]
pub struct ContactMonitor {
    rods: Vec<(String, RodInfo)>,
    /// (rod index, segment, corner, wall) of the contacts in force.
    active: Vec<(usize, usize, usize, &'static str)>,
    scratch: Vec<CornerState>,
    now: Vec<(usize, usize, usize, &'static str)>,
    /// Events in time order.
    pub events: Vec<ContactEvent>,
    /// Peak normal force.
    pub peak: Option<PeakForce>,
}

fn wall_name(w: Wall) -> &'static str {
    match w {
        Wall::Left => "left",
        Wall::Right => "right",
    }
}

impl ContactMonitor {
    /// Monitor the contacts of `rod` (named `rod` in the events).
    pub fn new(rod: RodInfo) -> Self {
        Self::with_rods(vec![("rod".to_string(), rod)])
    }

    /// Monitor the contacts of several named rods (a scenario's
    /// `[rod]`/`[[rod]]`s); `None` without rods.
    pub fn for_rods(rods: &[(String, RodInfo)]) -> Option<Self> {
        (!rods.is_empty()).then(|| Self::with_rods(rods.to_vec()))
    }

    fn with_rods(rods: Vec<(String, RodInfo)>) -> Self {
        Self {
            rods,
            active: Vec::new(),
            scratch: Vec::new(),
            now: Vec::new(),
            events: Vec::new(),
            peak: None,
        }
    }

    /// Time of the first contact start.
    pub fn first_contact(&self) -> Option<f64> {
        self.events.first().map(|e| e.t)
    }
}

impl Monitor for ContactMonitor {
    fn step(&mut self, t: f64, q: &[f64], qd: &[f64]) {
        self.now.clear();
        for (r, (name, rod)) in self.rods.iter().enumerate() {
            rod.corner_states(q, qd, &mut self.scratch);
            for c in &self.scratch {
                self.now
                    .push((r, c.segment + 1, c.corner, wall_name(c.wall)));
                if self.peak.as_ref().is_none_or(|p| c.normal_force > p.force) {
                    self.peak = Some(PeakForce {
                        rod: name.clone(),
                        force: c.normal_force,
                        t,
                        segment: c.segment + 1,
                        corner: c.corner,
                    });
                }
            }
        }
        let (rods, events) = (&self.rods, &mut self.events);
        let event = |kind, &(r, segment, corner, wall): &(usize, usize, usize, &'static str)| {
            ContactEvent {
                rod: rods[r].0.clone(),
                t,
                kind,
                segment,
                corner,
                wall,
            }
        };
        for key in &self.now {
            if !self.active.contains(key) {
                events.push(event("start", key));
            }
        }
        for key in &self.active {
            if !self.now.contains(key) {
                events.push(event("end", key));
            }
        }
        std::mem::swap(&mut self.active, &mut self.now);
    }

    fn report(&self, extra: &mut Map<String, Value>) {
        extra.insert(
            "first_contact_time".into(),
            self.first_contact().map_or(Value::Null, Value::from),
        );
        extra.insert(
            "contact_starts".into(),
            Value::from(self.events.iter().filter(|e| e.kind == "start").count()),
        );
        extra.insert(
            "peak_normal_force".into(),
            serde_json::to_value(&self.peak).unwrap_or(Value::Null),
        );
        extra.insert(
            "contact_events".into(),
            serde_json::to_value(&self.events).unwrap_or(Value::Null),
        );
    }
}

/// Contact periods and the peak normal force of one contact force element
/// (a scenario's `type = "contact"` `[[force]]`), as reported by
/// [`ElementContacts`].
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ElementContact {
    /// The `[[force]]`'s name.
    pub force: String,
    /// Time of the first accepted step in contact \[s\]; `None`: never.
    pub first_contact_time: Option<f64>,
    /// Times the contact started \[s\] (the first accepted step with
    /// penetration > 0 after one without).
    pub starts: Vec<f64>,
    /// Times it ended \[s\] (the first accepted step without penetration).
    pub ends: Vec<f64>,
    /// Largest normal force seen \[N\] (0 without contact).
    pub peak_normal_force: f64,
    /// When \[s\] (`None` without contact).
    pub peak_time: Option<f64>,
}

/// A [`Monitor`] of every contact force element of a system (those whose
/// [`crate::model::ForceElement::readings`] hold `normal_force` and
/// `penetration`): its starts and ends and its peak normal force, sampled
/// at accepted steps like [`ContactMonitor`] (an event's time is accurate
/// to one step; a contact shorter than a step may be missed).
#[derive(Debug)]
pub struct ElementContacts<'s> {
    system: &'s crate::model::System,
    /// (element index, column of the normal force, of the penetration).
    elements: Vec<(usize, usize, usize)>,
    active: Vec<bool>,
    values: Vec<f64>,
    /// One report per element, in the order given.
    pub contacts: Vec<ElementContact>,
}

impl<'s> ElementContacts<'s> {
    /// Monitor the named force elements `(name, index into
    /// System::forces)` of `system` that are contacts (others are
    /// skipped); `None` when none is.
    pub fn new(system: &'s crate::model::System, elements: &[(String, usize)]) -> Option<Self> {
        let mut chosen = Vec::new();
        let mut contacts = Vec::new();
        for (name, i) in elements {
            let Some(f) = system.forces().get(*i) else {
                continue;
            };
            let r = f.readings();
            let col = |q: &str| r.iter().position(|x| x.0 == q);
            if let (Some(n), Some(p)) = (col("normal_force"), col("penetration")) {
                chosen.push((*i, n, p));
                contacts.push(ElementContact {
                    force: name.clone(),
                    first_contact_time: None,
                    starts: Vec::new(),
                    ends: Vec::new(),
                    peak_normal_force: 0.0,
                    peak_time: None,
                });
            }
        }
        (!chosen.is_empty()).then(|| Self {
            system,
            active: vec![false; chosen.len()],
            elements: chosen,
            values: Vec::new(),
            contacts,
        })
    }
}

impl Monitor for ElementContacts<'_> {
    fn step(&mut self, t: f64, q: &[f64], qd: &[f64]) {
        for (k, &(i, n, p)) in self.elements.iter().enumerate() {
            let f = &self.system.forces()[i];
            self.values.clear();
            self.values.resize(f.readings().len(), 0.0);
            f.read(t, q, qd, &mut self.values);
            let (force, delta) = (self.values[n], self.values[p]);
            let c = &mut self.contacts[k];
            let on = delta > 0.0;
            if on && !self.active[k] {
                c.starts.push(t);
                c.first_contact_time.get_or_insert(t);
            } else if !on && self.active[k] {
                c.ends.push(t);
            }
            self.active[k] = on;
            if on && (c.peak_time.is_none() || force > c.peak_normal_force) {
                c.peak_normal_force = force;
                c.peak_time = Some(t);
            }
        }
    }

    fn report(&self, extra: &mut Map<String, Value>) {
        extra.insert(
            "contacts".into(),
            serde_json::to_value(&self.contacts).unwrap_or(Value::Null),
        );
    }
}
