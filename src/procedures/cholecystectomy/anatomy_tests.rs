use super::*;

fn anatomy() -> Anatomy {
    Anatomy::generate(&AnatomyParams::default()).expect("anatomy")
}

fn ellipsoid_volume(o: &OrganShape) -> f32 {
    4.0 / 3.0 * std::f32::consts::PI * o.semi_axes_m.x * o.semi_axes_m.y * o.semi_axes_m.z
}

#[test]
fn the_organs_hold_over_20000_particles_weighing_density_times_volume() {
    let a = anatomy();
    let params = AnatomyParams::default();
    assert!(a.organ_particles() >= 20_000, "{}", a.organ_particles());
    // Each particle weighs its cube of tissue, so an organ's mass is its density times its
    // volume (the lattice counts the volume to within a few per cent at these spacings).
    for (o, shape, tolerance) in [
        (&a.organs[0], &params.liver, 0.03),
        (&a.organs[1], &params.gallbladder, 0.05),
    ] {
        let per = shape.density_kg_per_m3 * shape.spacing_m.powi(3);
        for i in o.range.clone() {
            let w = a.particles.w[i as usize];
            assert!(
                w == 0.0 || (1.0 / w - per).abs() < 1e-6 * per,
                "particle {i}"
            );
        }
        let counted = o.range.len() as f32 * per;
        let want = shape.density_kg_per_m3 * ellipsoid_volume(shape);
        assert!(
            (counted - want).abs() < tolerance * want,
            "body {}: {counted} kg vs {want} kg",
            o.body
        );
    }
}

#[test]
fn no_two_bodies_start_inside_each_other() {
    let a = anatomy();
    let p = &a.particles;
    // Organs and vessels: particles of different bodies at least a lattice half-spacing
    // apart (ties and adhesions aside, which join them on purpose).
    let organ_or_vessel = |b: u16| b <= body::CYSTIC_ARTERY;
    let idx: Vec<usize> = (0..p.len())
        .filter(|&i| organ_or_vessel(p.body[i]))
        .collect();
    let mut closest = f32::INFINITY;
    let mut worst = (0, 0);
    for (n, &i) in idx.iter().enumerate() {
        for &j in &idx[n + 1..] {
            if p.body[i] != p.body[j] {
                let d = p.x[i].distance(p.x[j]);
                if d < closest {
                    closest = d;
                    worst = (i, j);
                }
            }
        }
    }
    assert!(closest > 0.001, "{closest} between {worst:?}");
}

#[test]
fn the_vessels_run_along_their_centrelines_and_meet_at_the_junction() {
    let a = anatomy();
    let params = AnatomyParams::default();
    let p = &a.particles;
    for (v, shape) in a.vessels.iter().zip([
        &params.cystic_duct,
        &params.common_hepatic_duct,
        &params.common_bile_duct,
        &params.cystic_artery,
    ]) {
        // Neighbours two radii apart (to the rounding of the length into whole gaps), each
        // on the centreline; the chain from the first point to the last but for the
        // junction's particle, which is the common hepatic duct's.
        let gap = 2.0 * v.radius_m;
        for w in v.chain.windows(2) {
            let d = p.x[w[0] as usize].distance(p.x[w[1] as usize]);
            assert!((d - gap).abs() < 0.25 * gap, "{d} vs {gap}");
        }
        for &i in &v.chain {
            assert!(distance_to_polyline(p.x[i as usize], &shape.points) < 1e-6);
        }
        let first = p.x[v.chain[0] as usize];
        let last = p.x[*v.chain.last().expect("chain") as usize];
        let (start, end) = (shape.points[0], *shape.points.last().expect("points"));
        match v.body {
            body::CYSTIC_DUCT => {
                assert!(first.distance(start) < 1e-6);
                assert!((last.distance(end) - gap).abs() < 0.25 * gap);
            }
            body::COMMON_BILE_DUCT => {
                assert!((first.distance(start) - gap).abs() < 0.25 * gap);
                assert!(last.distance(end) < 1e-6);
            }
            _ => {
                assert!(first.distance(start) < 1e-6);
                assert!(last.distance(end) < 1e-6);
            }
        }
    }
    // Calot's triangle is (neck, junction, hilum), with the junction shared.
    assert_eq!(
        a.calot[1],
        *params.cystic_duct.points.last().expect("points")
    );
    assert_eq!(
        a.calot[1],
        *params.common_hepatic_duct.points.last().expect("points")
    );
}

#[test]
fn adhesions_and_the_fascia_join_the_gallbladder_to_the_liver() {
    let a = anatomy();
    let p = &a.particles;
    assert!(a.adhesion_pairs.len() >= 30, "{}", a.adhesion_pairs.len());
    for &(g, l) in &a.adhesion_pairs {
        assert_eq!(p.body[g as usize], body::GALLBLADDER);
        assert_eq!(p.body[l as usize], body::LIVER);
        let d = p.x[g as usize].distance(p.x[l as usize]);
        assert!(d > 0.0 && d < 0.015, "{d}");
    }
    let [along, across] = AnatomyParams::default().fascia_nodes.map(|n| n as usize);
    assert_eq!(a.fascia.len(), along * across);
    assert_eq!(a.fascia_triangles.len(), 2 * (along - 1) * (across - 1));
    // Every fascia edge node is tied, to the gallbladder on one side and the liver on the
    // other.
    let tied_to = |n: u32| {
        a.ties
            .iter()
            .find(|t| t.0 == n)
            .map(|t| p.body[t.1 as usize])
    };
    for i in 0..along {
        assert_eq!(tied_to(a.fascia[i * across]), Some(body::GALLBLADDER));
        assert_eq!(
            tied_to(a.fascia[i * across + across - 1]),
            Some(body::LIVER)
        );
    }
}

#[test]
fn bad_figures_are_refused_naming_the_field() {
    let mut params = AnatomyParams::default();
    params.gallbladder.spacing_m = 0.0;
    let e = Anatomy::generate(&params).expect_err("refused");
    assert!(e.to_string().contains("anatomy.gallbladder"), "{e}");
    let mut params = AnatomyParams::default();
    params.cystic_artery.points.truncate(1);
    let e = Anatomy::generate(&params).expect_err("refused");
    assert!(e.to_string().contains("anatomy.cystic_artery"), "{e}");
}
