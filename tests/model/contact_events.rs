//! Contact events of every rod of a scenario (`events::ContactMonitor`
//! over `[[rod]]`s): two rods in one channel, thrown towards opposite
//! walls, each report their own contacts under their own names, at the
//! times the corners reach the walls by free flight (no gravity, no fluid).

use mbsolve::events::ContactMonitor;
use mbsolve::scenario;
use mbsolve::simulation::{self, Monitor};

const SCENARIO: &str = r#"
name = "two_rods_in_a_channel"
[[rod]]
name = "a"
segments = 4
position = [0.0, -0.1]
angle_deg = 0.0
length = 0.2
width = 0.01
velocity = [-0.5, 0.0]
contact = true
channel_width = 0.05
[[rod]]
name = "b"
segments = 4
position = [0.0, 0.3]
angle_deg = 0.0
length = 0.2
width = 0.01
velocity = [0.3, 0.0]
contact = true
channel_width = 0.05
[integrator]
method = "ode45"
rtol = 1e-8
atol = 1e-10
[time]
end = 0.08
[output]
dt = 0.001
"#;

#[test]
fn every_rod_reports_its_own_contacts() {
    let sc = scenario::parse(SCENARIO, "channel.toml", "channel", &[]).unwrap();
    assert!(sc.rod.is_none(), "[[rod]] only");
    let mut mon = ContactMonitor::for_rods(&sc.rods).expect("two rods");
    let mut monitors: Vec<&mut dyn Monitor> = vec![&mut mon];
    let (_, summary) =
        simulation::simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut monitors).unwrap();
    assert_eq!(summary.status, "completed", "{:?}", summary.message);
    // free flight until a corner (x = ∓w/2 off the centre line) reaches
    // its wall at ∓0.025 m
    let (w, d) = (0.01, 0.05);
    let t_a = (0.5 * d - 0.5 * w) / 0.5;
    let t_b = (0.5 * d - 0.5 * w) / 0.3;
    let first = |rod: &str| {
        mon.events
            .iter()
            .find(|e| e.rod == rod && e.kind == "start")
            .unwrap_or_else(|| panic!("no contact of rod {rod}: {:?}", mon.events))
            .clone()
    };
    let (ea, eb) = (first("a"), first("b"));
    println!("a: {ea:?} (free flight {t_a:.4}); b: {eb:?} ({t_b:.4})");
    assert_eq!(ea.wall, "left");
    assert_eq!(eb.wall, "right");
    // one accepted step of ode45 at rtol 1e-8 is far below 2e-3 s here
    assert!((ea.t - t_a).abs() < 2e-3, "{} vs {t_a}", ea.t);
    assert!((eb.t - t_b).abs() < 2e-3, "{} vs {t_b}", eb.t);
    assert!(mon
        .events
        .iter()
        .all(|e| (e.rod == "a") == (e.wall == "left")));
    assert_eq!(mon.first_contact(), Some(ea.t));
    let peak = mon.peak.as_ref().expect("a peak force");
    assert!(peak.force > 0.0 && (peak.rod == "a" || peak.rod == "b"));
}
