//! Radiometric calibration through the simulated sensor (`eoir::calibration`).

use eoir::calibration::{measured_netd, Calibration, CalibrationOptions};
use eoir::detector::{DetectorInstance, DetectorModel};
use eoir::sensor::{presets, SensorConfig};

fn sensor(extra: &[&str]) -> SensorConfig {
    let mut o: Vec<String> = [
        "detector.rows=64",
        "detector.cols=80",
        "detector.read_noise_e=200",
        "detector.fpn.prnu_sigma_rel=0.02",
        "detector.fpn.dsnu_sigma_e=2e4",
        "detector.auto_gain.reference_temperature_k=300",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    o.extend(extra.iter().map(|s| s.to_string()));
    presets::load("multimir", &[], &o).unwrap()
}

#[test]
fn explore() {
    let s = sensor(&[]);
    let model = DetectorModel::from_config(&s).unwrap();
    let inst = DetectorInstance::new(&model, 7).unwrap();
    let cal = Calibration::new(&s, &model, &inst, &CalibrationOptions::default()).unwrap();
    println!("K {} lut {:?} e300 {}", model.gain_dn_per_e(), cal.lut_range_k(), cal.blackbody_electrons(300.0).unwrap());
    println!("bad {}", cal.bad_pixels().count());
    println!("rnu {:?}", cal.residual_nonuniformity(&inst, 310.0).unwrap());
    println!("netd {}", cal.netd_analytic_k(300.0).unwrap());
    println!("meas {}", measured_netd(&s, &inst, 300.0, 0.25, 16, Some(cal.bad_pixels())).unwrap());
}
