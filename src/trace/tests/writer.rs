//! The streaming writer: a killed session, a full disk, the wall interval, refused input.

use super::*;

#[test]
fn a_session_killed_mid_way_keeps_all_but_its_last_second() {
    let rec = recording("0.002", 0);
    let dir = dir("killed");
    let path = dir.join("input.vtrace");
    let mut w = RecordingWriter::create(&path, &header(&rec)).expect("create");
    let pushed: Vec<InputFrame> = (0..1150).map(frame).collect(); // 2.3 s
    for f in &pushed {
        w.push_frame(f).expect("push");
    }
    assert_eq!(w.frames_written(), 1150);
    drop(w);
    let back = Recording::read(&path).expect("a killed session's file reads");
    assert!(
        matches!(back.tail, Tail::Cut { dropped_bytes: 0, complete_blocks } if complete_blocks >= 3),
        "{:?}",
        back.tail
    );
    assert!(back.frames.len() >= 1150 - 500, "{}", back.frames.len());
    assert_eq!(back.frames, pushed[..back.frames.len()]);
    assert_eq!(
        (back.session_id.as_str(), back.dt_s),
        (rec.session_id.as_str(), 0.002)
    );
}

/// A disk that fills after `budget` bytes, and whose sync fails if `sync_fails`.
struct FullDisk<'a> {
    budget: usize,
    bytes: &'a mut Vec<u8>,
    sync_fails: bool,
}

impl Write for FullDisk<'_> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if self.budget == 0 {
            return Err(io::Error::new(io::ErrorKind::StorageFull, "disk full"));
        }
        let n = buf.len().min(self.budget);
        self.budget -= n;
        self.bytes.extend_from_slice(&buf[..n]);
        Ok(n)
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl RecordingSink for FullDisk<'_> {
    fn sync_all(&mut self) -> io::Result<()> {
        match self.sync_fails {
            true => Err(io::Error::other("sync failed")),
            false => Ok(()),
        }
    }
}

/// A scripted session (150 frames at 10 ms, a tuning, a frame, flushes, finish) into a disk of
/// `budget` bytes: the index of the call that failed first (0: creating the writer) and the
/// bytes that reached the disk. Checks that the disk's error comes back, and that every call
/// after it fails too.
fn session_into(budget: usize) -> (Option<usize>, Vec<u8>) {
    let rec = recording("0.01", 0);
    let mut bytes = Vec::new();
    let disk = FullDisk {
        budget,
        bytes: &mut bytes,
        sync_fails: false,
    };
    let mut results = Vec::new();
    match RecordingWriter::with_sink(disk, Path::new("full.vtrace"), &header(&rec)) {
        Err(e) => results.push(Err(e.kind())),
        Ok(w) => {
            results.push(Ok(()));
            let mut w = w.with_wall_interval(Duration::from_secs(3600));
            for i in 0..150 {
                results.push(w.push_frame(&frame(i)).map_err(|e| e.kind()));
            }
            results.push(w.push_tuning(&tuned(150, 5.0e6)).map_err(|e| e.kind()));
            results.push(w.push_frame(&frame(150)).map_err(|e| e.kind()));
            results.push(w.flush_if_due().map_err(|e| e.kind()));
            results.push(w.flush().map_err(|e| e.kind()));
            results.push(w.finish("completed").map_err(|e| e.kind()));
        }
    }
    let first = results.iter().position(|r| r.is_err());
    if let Some(f) = first {
        assert_eq!(
            results[f],
            Err(io::ErrorKind::StorageFull),
            "budget {budget}"
        );
        assert!(
            results[f..].iter().all(|r| r.is_err()),
            "budget {budget}: {results:?}"
        );
    }
    (first, bytes)
}

#[test]
fn a_full_disk_is_reported_and_leaves_a_readable_prefix() {
    let (first, whole) = session_into(usize::MAX);
    assert_eq!(first, None);
    let full = Recording::decode("full.vtrace", &whole).expect("sound");
    assert_eq!(full.frames.len(), 151);
    let header_end = block_spans(&whole)[0].1;
    let mut failed_calls = std::collections::BTreeSet::new();
    for budget in (0..whole.len()).step_by(7).chain([whole.len() - 1]) {
        let (first, bytes) = session_into(budget);
        let first = first.unwrap_or_else(|| panic!("budget {budget} must fail"));
        failed_calls.insert(first);
        if budget < header_end {
            assert_eq!(first, 0, "budget {budget}");
            continue;
        }
        let r = Recording::decode("full.vtrace", &bytes)
            .unwrap_or_else(|e| panic!("budget {budget}: {e}"));
        assert!(matches!(r.tail, Tail::Cut { .. }), "budget {budget}");
        assert_eq!(r.frames, full.frames[..r.frames.len()], "budget {budget}");
    }
    // Creating, the push that fills a block (frame 100), the tuning, flush and finish each met
    // the full disk.
    assert_eq!(
        failed_calls.into_iter().collect::<Vec<_>>(),
        [0, 100, 151, 154, 155]
    );
}

#[test]
fn a_failed_sync_is_reported_by_finish() {
    let rec = recording("0.01", 0);
    let mut bytes = Vec::new();
    let disk = FullDisk {
        budget: usize::MAX,
        bytes: &mut bytes,
        sync_fails: true,
    };
    let mut w =
        RecordingWriter::with_sink(disk, Path::new("s.vtrace"), &header(&rec)).expect("create");
    w.push_frame(&frame(0)).expect("push");
    let e = w.finish("completed").expect_err("sync fails");
    assert_eq!(e.to_string(), "sync failed");
    // The bytes themselves are complete.
    let r = Recording::decode("s.vtrace", &bytes).expect("reads");
    assert_eq!(
        r.tail,
        Tail::Ended {
            how: "completed".into()
        }
    );
}

#[test]
fn a_frame_waits_at_most_the_wall_interval() {
    let rec = recording("0.002", 0);
    let dir = dir("wall");
    let path = dir.join("input.vtrace");
    let mut w = RecordingWriter::create(&path, &header(&rec))
        .expect("create")
        .with_wall_interval(Duration::from_millis(1));
    w.push_frame(&frame(0)).expect("push");
    std::thread::sleep(Duration::from_millis(5));
    w.push_frame(&frame(1)).expect("push");
    // Two frames are far from a simulated second: only the wall interval wrote them.
    let r = Recording::read(&path).expect("reads while the session runs");
    assert!(matches!(r.tail, Tail::Cut { .. }));
    assert_eq!(r.frames.first(), Some(&frame(0)));
    // An idle session's frames go out through flush_if_due.
    w.push_frame(&frame(2)).expect("push");
    std::thread::sleep(Duration::from_millis(5));
    w.flush_if_due().expect("flush");
    let r = Recording::read(&path).expect("reads");
    assert_eq!(r.frames, [frame(0), frame(1), frame(2)]);
    assert_eq!(w.path(), path);
    w.finish("completed").expect("finish");
}

#[test]
fn a_non_finite_frame_or_bad_tuning_is_refused_and_the_writer_goes_on() {
    let rec = recording("0.01", 0);
    let dir = dir("refuse");
    let path = dir.join("input.vtrace");
    let mut w = RecordingWriter::create(&path, &header(&rec)).expect("create");
    w.push_frame(&frame(0)).expect("push");
    let mut nan = frame(1);
    nan.hands[0].pose.position.x = f32::NAN;
    let e = w.push_frame(&nan).expect_err("nan");
    assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
    let e = w
        .push_tuning(&tuned(2, 5.0e6))
        .expect_err("past the frames");
    assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
    w.push_tuning(&tuned(1, 5.0e6)).expect("tuning");
    let e = w
        .push_tuning(&tuned(0, 5.0e6))
        .expect_err("before the previous");
    assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
    w.push_frame(&frame(1)).expect("push");
    assert_eq!(w.frames_written(), 2);
    w.finish("error").expect("finish");
    let r = Recording::read(&path).expect("reads");
    assert_eq!(r.frames, [frame(0), frame(1)]);
    assert_eq!(r.tunings, [tuned(1, 5.0e6)]);
    assert_eq!(
        r.tail,
        Tail::Ended {
            how: "error".into()
        }
    );
}

#[test]
fn a_frames_block_holds_one_simulated_second() {
    use crate::trace::stream::frames_per_block;
    let got = [0.01f32, 0.002, 0.001, 0.003, 1e-4].map(frames_per_block);
    assert_eq!(got, [100, 500, 1000, 334, 10_000]);
}
