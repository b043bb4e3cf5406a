//! The format: round trips, truncation, corruption, the header's dt, versions 1 and 2.

use super::*;

#[test]
fn a_recording_reads_back_as_written() {
    // Three simulated seconds and a bit: several frames blocks, tunings at step 0, mid-session
    // (two at one step) and after the last frame.
    let rec = recording("0.002", 1603);
    let dir = dir("round-trip");
    let path = dir.join("input.vtrace");
    rec.write(&path).expect("write");
    assert_eq!(Recording::read(&path).expect("reads"), rec);
    assert!(!dir.join("input.vtrace.partial").exists());
    // A cut recording written again says it was interrupted.
    let cut = Recording {
        tail: Tail::Cut {
            complete_blocks: 3,
            dropped_bytes: 10,
        },
        ..rec.clone()
    };
    cut.write(&path).expect("write");
    let back = Recording::read(&path).expect("reads");
    assert_eq!(
        back.tail,
        Tail::Ended {
            how: "interrupted".into()
        }
    );
    assert_eq!(back.frames, rec.frames);
}

#[test]
fn tunings_out_of_order_are_not_written() {
    let mut rec = recording("0.01", 20);
    rec.tunings.swap(0, 1);
    let dir = dir("out-of-order");
    let path = dir.join("input.vtrace");
    let e = rec.write(&path).expect_err("out of order");
    assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
    assert!(!path.exists() && !path.with_extension("vtrace.partial").exists());
}

#[test]
fn a_file_cut_anywhere_after_its_header_reads_as_a_prefix() {
    let rec = recording("0.01", 250);
    let (bytes, _dir) = bytes_of(&rec, "truncate");
    let spans = block_spans(&bytes);
    // Header, tuning 0, frames 0..99, frames 100..124, two tunings at 125, frames 125..224,
    // frames 225..249, tuning 250, end.
    assert_eq!(spans.len(), 10);
    let header_end = spans[0].1;
    let mut last_blocks = 0;
    for n in header_end..=bytes.len() {
        let r = Recording::decode("cut.vtrace", &bytes[..n])
            .unwrap_or_else(|e| panic!("cut at {n}: {e}"));
        assert_eq!(r.frames, rec.frames[..r.frames.len()], "cut at {n}");
        assert_eq!(r.tunings, rec.tunings[..r.tunings.len()], "cut at {n}");
        assert_eq!((r.dt_s, &r.scenario), (rec.dt_s, &rec.scenario));
        if n == bytes.len() {
            assert_eq!(r, rec);
            break;
        }
        let Tail::Cut {
            complete_blocks,
            dropped_bytes,
        } = r.tail
        else {
            panic!("cut at {n}: {:?}", r.tail)
        };
        let whole = spans[complete_blocks as usize - 1].1;
        assert_eq!(dropped_bytes as usize, n - whole, "cut at {n}");
        assert!(complete_blocks >= last_blocks);
        last_blocks = complete_blocks;
    }
    for n in [0, 5, PREAMBLE_BYTES, header_end - 1] {
        assert!(Recording::decode("cut.vtrace", &bytes[..n]).is_err(), "{n}");
    }
}

#[test]
fn every_flipped_byte_is_an_error_naming_its_block() {
    let mut rec = recording("0.01", 12);
    rec.scenario = "dt_s = 0.01".into();
    let (bytes, _dir) = bytes_of(&rec, "flip");
    let spans = block_spans(&bytes);
    assert!(bytes.len() < 2000, "{}", bytes.len());
    for at in 0..bytes.len() {
        for mask in [0x01u8, 0x80, 0xff] {
            let mut bad = bytes.clone();
            bad[at] ^= mask;
            let e = Recording::decode("flip.vtrace", &bad)
                .expect_err(&format!("byte {at} ^ {mask:#x} must be caught"));
            if let Some(n) = spans.iter().position(|(s, e)| (*s..*e).contains(&at)) {
                assert_eq!(e.key, format!("block {n}"), "byte {at}: {e}");
                assert!(e.message.contains("corrupted"), "byte {at}: {e}");
            } else {
                assert!(at < PREAMBLE_BYTES, "{at}");
            }
        }
    }
}

#[test]
fn a_corrupted_frames_block_says_which_frames() {
    let rec = recording("0.002", 1203);
    let (mut bytes, _dir) = bytes_of(&rec, "which-frames");
    let spans = block_spans(&bytes);
    // Header, tuning 0, frames 0..499, frames 500..600 (pushed out by the tunings at 601).
    bytes[spans[3].0 + 100] ^= 4;
    let e = Recording::decode("r.vtrace", &bytes).expect_err("corrupt");
    assert_eq!(e.key, "block 3");
    assert!(
        e.message.contains("payload checksum mismatch") && e.message.contains("frames 500..600"),
        "{e}"
    );
}

#[test]
fn a_dt_unlike_the_scenarios_is_rejected() {
    let ok = v3(&[(
        0,
        BlockKind::Header,
        header_payload(0.002, &scenario("0.002")),
    )]);
    let r = Recording::decode("r.vtrace", &ok).expect("matching dt");
    assert_eq!(
        r.tail,
        Tail::Cut {
            complete_blocks: 1,
            dropped_bytes: 0
        }
    );
    assert_eq!((r.session_id.as_str(), r.frames.len()), ("id", 0));
    let int = v3(&[(0, BlockKind::Header, header_payload(0.002, "dt_s = 0.002"))]);
    assert!(Recording::decode("r.vtrace", &int).is_ok());
    for (text, says) in [
        (scenario("0.001"), "its scenario says 0.001 s"),
        ("[tissue]\ndt_s = 0.002".into(), "no numeric dt_s"),
        ("dt_s = \"0.002\"".into(), "no numeric dt_s"),
    ] {
        let bad = v3(&[(0, BlockKind::Header, header_payload(0.002, &text))]);
        let e = Recording::decode("r.vtrace", &bad).expect_err(&text);
        assert_eq!(e.key, "dt_s", "{e}");
        assert!(
            e.message.contains("header says 0.002 s") && e.message.contains(says),
            "{e}"
        );
    }
    let bad = v3(&[(0, BlockKind::Header, header_payload(0.002, "dt_s = ="))]);
    let e = Recording::decode("r.vtrace", &bad).expect_err("not TOML");
    assert_eq!(e.key, "scenario", "{e}");
    // The writer refuses such a header before touching the file.
    let dir = dir("dt");
    let path = dir.join("input.vtrace");
    let text = scenario("0.001");
    let h = RecordingHeader {
        session_id: "",
        procedure: procedure(),
        dt_s: 0.002,
        scenario: &text,
    };
    let e = RecordingWriter::create(&path, &h)
        .err()
        .expect("dt mismatch");
    assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
    assert!(e.to_string().contains("dt_s"), "{e}");
    assert!(!path.exists());
}

#[test]
fn structural_errors_name_the_block_and_what_is_wrong() {
    let h = || (0, BlockKind::Header, header_payload(0.01, "dt_s = 0.01"));
    let fr = |seq, first: u64, n: usize| {
        (
            seq,
            BlockKind::Frames,
            frames_payload(first, &(0..n).map(frame).collect::<Vec<_>>()),
        )
    };
    let end = |seq, total| (seq, BlockKind::End, end_payload(total, "completed"));
    let mut nan = frame(0);
    nan.hands[1].buttons.grip = f32::NAN;
    // A flag byte with a pad press code past right (5): the first hand's flags end its
    // 9 floats.
    let mut bad_pad = frames_payload(0, &[frame(0)]);
    bad_pad[12 + 36] = 5 << 1;
    let mut bad_utf8 = header_payload(0.01, "dt_s = 0.01");
    bad_utf8[4] = 0xff; // inside the session id
    let unknown = {
        let mut b = v3(&[h()]);
        let mut x = Vec::new();
        blocks::encode(1, BlockKind::End, &[b"x"], &mut x).expect("encode");
        x[4] = 9; // an unknown kind, with sound checksums
        let crc = crc32fast::hash(&x[..9]);
        x[9..13].copy_from_slice(&crc.to_le_bytes());
        b.extend_from_slice(&x);
        b
    };
    let cases: Vec<(Vec<u8>, &str, &str)> = vec![
        (v3(&[fr(0, 0, 1)]), "block 0", "header block comes first"),
        (
            v3(&[h(), fr(2, 0, 1)]),
            "block 1",
            "sequence number 2, expected 1",
        ),
        (
            v3(&[
                h(),
                (1, BlockKind::Header, header_payload(0.01, "dt_s = 0.01")),
            ]),
            "block 1",
            "header block comes first",
        ),
        (unknown, "block 1", "unknown block kind 9"),
        (
            v3(&[h(), fr(1, 0, 3), fr(2, 2, 1)]),
            "block 2",
            "first step 2, expected 3",
        ),
        (
            v3(&[h(), end(1, 1)]),
            "block 1",
            "says 1 frames, the file has 0",
        ),
        (
            v3(&[h(), end(1, 0), end(2, 0)]),
            "block 2",
            "follow the end block",
        ),
        (
            v3(&[(0, BlockKind::Header, bad_utf8)]),
            "block 0",
            "session id: is not UTF-8",
        ),
        (
            v3(&[h(), (1, BlockKind::Frames, frames_payload(0, &[nan]))]),
            "block 1",
            "frame 0: pose or button is not a finite number",
        ),
        (
            v3(&[h(), (1, BlockKind::Frames, bad_pad)]),
            "block 1",
            "frame 0: button flags 0b00001010: only the mark bit and a pad press 0-4 exist",
        ),
        (
            v3(&[
                h(),
                (
                    1,
                    BlockKind::Frames,
                    frames_payload(0, &[frame(0)])[..20].to_vec(),
                ),
            ]),
            "block 1",
            "74 bytes for 1 frames, found 8",
        ),
        (
            v3(&[
                h(),
                (1, BlockKind::Tuning, tuning_payload(1, &[(b"a", 1.0)])),
            ]),
            "block 1",
            "step 1 is out of order or past the last frame (0)",
        ),
        (
            v3(&[
                h(),
                fr(1, 0, 2),
                (2, BlockKind::Tuning, tuning_payload(2, &[])),
                (3, BlockKind::Tuning, tuning_payload(1, &[])),
            ]),
            "block 3",
            "out of order",
        ),
        (
            v3(&[
                h(),
                (
                    1,
                    BlockKind::Tuning,
                    tuning_payload(0, &[(b"a", f32::INFINITY)]),
                ),
            ]),
            "block 1",
            "a is not a finite number",
        ),
        (
            v3(&[
                h(),
                (1, BlockKind::End, [end_payload(0, "x"), vec![0]].concat()),
            ]),
            "block 1",
            "1 bytes left over",
        ),
    ];
    for (i, (bytes, key, says)) in cases.iter().enumerate() {
        let e = Recording::decode("r.vtrace", bytes).expect_err(&format!("case {i}"));
        assert_eq!(
            (e.file.as_str(), e.key.as_str()),
            ("r.vtrace", *key),
            "case {i}: {e}"
        );
        assert!(e.message.contains(says), "case {i}: {e}");
    }
    // Trailing bytes after the end, even too few for a block, are not a cut but corruption.
    let mut b = v3(&[h(), end(1, 0)]);
    b.push(0);
    let e = Recording::decode("r.vtrace", &b).expect_err("after end");
    assert!(
        e.key == "block 2" && e.message.contains("1 bytes follow the end block"),
        "{e}"
    );
    // And a sound one ends.
    let b = v3(&[h(), fr(1, 0, 3), end(2, 3)]);
    let r = Recording::decode("r.vtrace", &b).expect("sound");
    assert_eq!(
        r.tail,
        Tail::Ended {
            how: "completed".into()
        }
    );
    assert_eq!(r.frames.len(), 3);
}

/// Versions 1 and 2 as the previous `Recording::write` made them.
fn legacy_bytes(version: u32, rec: &Recording, tunings: &[(u64, Tuning)]) -> Vec<u8> {
    let mut buf = b"VSLTRACE".to_vec();
    buf.extend_from_slice(&version.to_le_bytes());
    for s in [rec.procedure.as_bytes(), rec.scenario.as_bytes()] {
        put_str(&mut buf, s);
    }
    buf.extend_from_slice(&rec.dt_s.to_le_bytes());
    buf.extend_from_slice(&(rec.frames.len() as u64).to_le_bytes());
    for f in &rec.frames {
        encode_frame(f, &mut buf);
    }
    if version >= 2 {
        buf.extend_from_slice(&(tunings.len() as u32).to_le_bytes());
        for (step, t) in tunings {
            buf.extend_from_slice(&step.to_le_bytes());
            // Versions 1 and 2 stored spring, damping, a tool pressure and offset.
            let [spring, damping, offset] = t.values();
            for v in [spring, damping, 1500.0, offset] {
                buf.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    buf
}

#[test]
fn versions_1_and_2_still_read() {
    let rec = recording("0.002", 7);
    let t = |foundation_pa_per_m| Tuning {
        foundation_pa_per_m,
        damping_per_s: 4.0,
        offset_m: 0.002,
    };
    let tunings = [(0, t(6.0e6)), (3, t(7.0e6)), (7, t(8.0e6))];
    let legacy = Recording {
        session_id: String::new(),
        tunings: vec![],
        tail: Tail::Ended {
            how: "legacy".into(),
        },
        ..rec.clone()
    };
    let v1 = Recording::decode("v1.vtrace", &legacy_bytes(1, &rec, &tunings)).expect("v1");
    assert_eq!(v1, legacy);
    let mut v2 = Recording::decode("v2.vtrace", &legacy_bytes(2, &rec, &tunings)).expect("v2");
    // Their tunings name no model until the procedure's is given to them.
    assert!(v2.tunings.iter().all(|t| t.model.is_empty()));
    let e = v2
        .clone()
        .name_legacy_tunings("v2.vtrace", None)
        .expect_err("no model for them");
    assert!(
        e.key == "tuning 0" && e.message.contains("never had tunings"),
        "{e}"
    );
    v2.name_legacy_tunings("v2.vtrace", Some(tuned_model()))
        .expect("named");
    assert_eq!(v2.frames, rec.frames);
    assert_eq!(v2.tunings.len(), 3);
    let names: Vec<&str> = v2.tunings[1]
        .values
        .iter()
        .map(|(n, _)| n.as_str())
        .collect();
    assert_eq!(names, ["foundation_pa_per_m", "damping_per_s", "offset_m"]);
    assert_eq!(v2.tunings[1].model, tuned_model());
    assert_eq!(v2.tunings[1].values[0].1, 7.0e6);
    for (r, (step, t)) in v2.tunings.iter().zip(&tunings) {
        assert_eq!((r.step, r.to_tuning()), (*step, Ok(*t)));
    }
    assert_eq!(
        v2,
        Recording {
            tunings: v2.tunings.clone(),
            ..legacy
        }
    );
    // Still checked as before.
    let mut bad = legacy_bytes(2, &rec, &tunings);
    let n = bad.len();
    bad[n - 12..n - 8].copy_from_slice(&(-3.0f32).to_le_bytes());
    let e = Recording::decode("v2.vtrace", &bad).expect_err("negative damping");
    assert!(
        e.key == "tuning 2: damping_per_s" && e.message.contains("-3"),
        "{e}"
    );
    let bytes = legacy_bytes(1, &rec, &[]);
    let e = Recording::decode("v1.vtrace", &bytes[..bytes.len() - 5]).expect_err("cut v1");
    assert_eq!(e.key, "frames", "{e}");
    let mut future = bytes.clone();
    future[8] = 4;
    let e = Recording::decode("v4.vtrace", &future).expect_err("v4");
    assert!(
        e.key == "version" && e.message.contains("unsupported version 4"),
        "{e}"
    );
}

#[test]
fn a_tuning_record_maps_to_a_soft_body_tuning_only_when_complete_and_in_range() {
    let r = tuned(5, 6.0e6);
    assert_eq!(r.to_tuning().map(|t| t.foundation_pa_per_m), Ok(6e6));
    let mut missing = r.clone();
    missing.values.pop();
    assert_eq!(
        missing.to_tuning(),
        Err(TuningRecordError::Missing {
            model: r.model.clone(),
            name: "offset_m"
        })
    );
    assert!(
        missing
            .to_tuning()
            .is_err_and(|e| e.to_string().contains("offset_m is missing"))
    );
    let mut twice = r.clone();
    twice.values[2].0 = "damping_per_s".into();
    assert!(
        twice
            .to_tuning()
            .is_err_and(|e| e.to_string().contains("given twice"))
    );
    let mut unknown = r.clone();
    unknown.values[0].0 = "stiffness".into();
    assert!(
        unknown
            .to_tuning()
            .is_err_and(|e| e.to_string().contains("stiffness"))
    );
    assert!(tuned(5, -1.0).to_tuning().is_err_and(|e| {
        e.to_string()
            .contains(&format!("{}.foundation_pa_per_m", tuned_model()))
    }));
}
