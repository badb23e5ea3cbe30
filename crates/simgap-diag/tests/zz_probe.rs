use simgap_core::Formulation;
use simgap_diag::{diagnose, DiagnoseOptions};
#[test]
fn probe() {
    let i: usize = std::env::var("PROBE_I").unwrap().parse().unwrap();
    let kind = std::env::var("PROBE_KIND").unwrap_or("servo".into());
    let sc = match kind.as_str() {
        "backlash" => simgap_diag::selfcheck::backlash_scenario(1, i),
        "offset" => simgap_diag::selfcheck::encoder_offset_scenario(1, i),
        "draw2" => simgap_diag::selfcheck::servo_draw(2, i, false),
        _ => simgap_diag::selfcheck::servo_scenario(1, i),
    }
    .unwrap();
    let options = DiagnoseOptions { directional_friction: sc.directional_friction, load_stribeck_friction: sc.load_stribeck_friction, ..DiagnoseOptions::default() };
    let t0 = std::time::Instant::now();
    let mut last = (String::new(), t0, simgap_diag::cost::cost());
    let fit = sc.fit.clone();
    let d = diagnose(&sc.diagnosis_model, Formulation::EulerLagrange, &fit, &sc.holdout, &options, &mut |p| {
        if p.stage != last.0 {
            let c = simgap_diag::cost::cost();
            eprintln!("{:<28} {:6.2}s {:>12} steps", last.0, last.1.elapsed().as_secs_f64(), (c - last.2).steps);
            last = (p.stage.to_string(), std::time::Instant::now(), c);
        }
    })
    .unwrap();
    let c = simgap_diag::cost::cost();
    eprintln!("{:<28} {:6.2}s {:>12} steps", last.0, last.1.elapsed().as_secs_f64(), (c - last.2).steps);
    eprintln!("total {:.2}s; fit runs {} samples {:?}", t0.elapsed().as_secs_f64(), fit.len(), fit.iter().map(|r| r.t.len()).collect::<Vec<_>>());
    if std::env::var("PROBE_SUMMARY").is_ok() {
        eprintln!("SEL {}", serde_json::to_string(&d.report.selected_effects).unwrap());
        eprintln!("DROP {}", serde_json::to_string(&d.report.dropped_effects).unwrap());
    }
    eprintln!("selected {:?}", d.report.selected_effects.iter().map(|e| format!("{}@{:?}", e.effect, e.joints)).collect::<Vec<_>>());
    for n in &d.report.notes {
        if true {
            eprintln!("NOTE {}", n);
        }
    }
}
