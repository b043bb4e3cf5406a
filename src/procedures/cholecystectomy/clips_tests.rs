use super::*;

/// A straight vessel of 11 particles 2 mm apart along +x from the origin, as chain 0.
fn vessel() -> (Particles, Chains) {
    let mut p = Particles::new();
    let ids: Vec<u32> = (0..11)
        .map(|k| p.add(Vec3::new(0.002 * k as f32, 0.0, 0.0), 1e-4, 3))
        .collect();
    let mut c = Chains::new();
    c.add(&p, &ids, 100.0, 0.0);
    (p, c)
}

fn duct() -> Clippable {
    // The patient at the chain's last particle (towards the common bile duct).
    Clippable {
        chain: 0,
        name: "cystic_duct",
        patient: PatientEnd::Last,
        error: CutError::BileLeak,
    }
}

#[test]
fn three_clips_and_a_cut_between_them_is_safe_and_recorded_in_order() {
    let (p, mut c) = vessel();
    let mut r = ClipRecord::default();
    let v = duct();
    // Two on the patient side (at 15 and 17 mm), one towards the gallbladder (at 5 mm),
    // each from a jaw 1 mm off the centreline.
    for (x, t) in [(0.015, 1.0), (0.017, 2.0), (0.005, 3.0)] {
        let clip = r
            .clip(&c, &p, &v, Vec3::new(x, 0.001, 0.0), 0.003, t)
            .expect("on the duct");
        assert!((clip.at_m - x).abs() < 1e-6, "{clip:?}");
        assert_eq!(clip.position, [x, 0.0, 0.0]);
    }
    // Too far from the duct: no clip.
    assert!(
        r.clip(&c, &p, &v, Vec3::new(0.01, 0.01, 0.0), 0.003, 4.0)
            .is_none()
    );
    let cut = r
        .cut(&mut c, &p, &v, Vec3::new(0.011, 0.0005, 0.0), 0.003, 5.0)
        .expect("cut");
    assert_eq!((cut.clips_patient_side, cut.clips_gallbladder_side), (2, 1));
    assert_eq!(cut.error, None);
    assert!(!c.is_intact(0, 5), "the segment from 10 to 12 mm is cut");
    let order: Vec<f32> = r.clips.iter().map(|c| c.at_m).collect();
    assert_eq!(order.len(), 3);
    assert!((order[0] - 0.015).abs() < 1e-6 && (order[2] - 0.005).abs() < 1e-6);
    // The record as the report will carry it.
    let json = serde_json::to_value(&r).expect("json");
    assert_eq!(json["clips"].as_array().map(Vec::len), Some(3));
    assert_eq!(json["cuts"][0]["clips_patient_side"], 2);
    assert_eq!(json["cuts"][0]["error"], serde_json::Value::Null);
}

#[test]
fn a_cut_with_fewer_than_two_clips_on_the_patient_side_is_an_error() {
    let (p, mut c) = vessel();
    let mut r = ClipRecord::default();
    let v = duct();
    r.clip(&c, &p, &v, Vec3::new(0.015, 0.0, 0.0), 0.003, 1.0);
    r.clip(&c, &p, &v, Vec3::new(0.005, 0.0, 0.0), 0.003, 2.0);
    r.clip(&c, &p, &v, Vec3::new(0.003, 0.0, 0.0), 0.003, 3.0);
    let cut = r
        .cut(&mut c, &p, &v, Vec3::new(0.011, 0.0, 0.0), 0.003, 4.0)
        .expect("cut");
    assert_eq!((cut.clips_patient_side, cut.clips_gallbladder_side), (1, 2));
    assert_eq!(cut.error, Some(CutError::BileLeak));
    // The same place again: already cut, nothing more.
    assert!(
        r.cut(&mut c, &p, &v, Vec3::new(0.011, 0.0, 0.0), 0.003, 5.0)
            .is_none()
    );
    // The artery, patient at its first particle, cut unclipped: bleeding.
    let artery = Clippable {
        chain: 0,
        name: "cystic_artery",
        patient: PatientEnd::First,
        error: CutError::Bleeding,
    };
    let cut = r
        .cut(&mut c, &p, &artery, Vec3::new(0.004, 0.0, 0.0), 0.003, 6.0)
        .expect("cut");
    assert_eq!(cut.clips_patient_side, 0);
    assert_eq!(cut.error, Some(CutError::Bleeding));
    assert_eq!(r.clips_on("cystic_duct"), 3);
    assert_eq!(r.clips_on("cystic_artery"), 0);
}
