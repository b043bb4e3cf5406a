//! The records on a real PostgreSQL server (Debian's `postgresql`, started by the test in a
//! scratch folder on a loopback port): eight stations storing at once, one session stored by
//! all eight, nothing lost or doubled; a station that starts before the server waits for it;
//! a server that cannot be reached leaves the session listed for `records sync`.

mod common;
use common::{bin, ok, report, run_sandbox, tmp};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use vesalius::records::Db;

/// PostgreSQL's programs: the newest version's `bin` under /usr/lib/postgresql.
fn pg_bin() -> PathBuf {
    let mut versions: Vec<PathBuf> = std::fs::read_dir("/usr/lib/postgresql")
        .expect("PostgreSQL's programs (apt-get install postgresql)")
        .filter_map(|e| e.ok().map(|e| e.path().join("bin")))
        .filter(|b| b.join("initdb").exists())
        .collect();
    versions.sort();
    versions.pop().expect("an initdb under /usr/lib/postgresql")
}

/// A command as the `postgres` user when we are root (the server refuses to run as root).
fn as_server_user(program: &Path) -> Command {
    let root = Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0");
    if root {
        let mut c = Command::new("runuser");
        c.args(["-u", "postgres", "--"]).arg(program);
        c
    } else {
        Command::new(program)
    }
}

fn id_of(flag: &str) -> u32 {
    let o = Command::new("id")
        .args([flag, "postgres"])
        .output()
        .expect("id");
    String::from_utf8_lossy(&o.stdout)
        .trim()
        .parse()
        .expect("the postgres user")
}

/// A free loopback port.
fn free_port() -> u16 {
    let l = std::net::TcpListener::bind("127.0.0.1:0").expect("a port");
    l.local_addr().expect("addr").port()
}

/// A server's data folder, made by initdb (not yet started).
struct Server {
    data: PathBuf,
    port: u16,
    child: Option<Child>,
}

impl Server {
    fn init(dir: &Path) -> Server {
        let data = dir.join("pgdata");
        std::fs::create_dir_all(&data).expect("data dir");
        if as_server_user(Path::new("true")).get_program() == "runuser" {
            std::os::unix::fs::chown(dir, Some(id_of("-u")), Some(id_of("-g"))).expect("chown");
            std::os::unix::fs::chown(&data, Some(id_of("-u")), Some(id_of("-g"))).expect("chown");
        }
        let o = as_server_user(&pg_bin().join("initdb"))
            .args(["-A", "trust", "-U", "vesalius", "--no-sync", "-D"])
            .arg(&data)
            .output()
            .expect("initdb");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        Server {
            data,
            port: free_port(),
            child: None,
        }
    }

    fn url(&self) -> String {
        format!("postgres://vesalius@127.0.0.1:{}/postgres", self.port)
    }

    /// Starts the server and waits until it takes connections.
    fn start(&mut self) {
        let child = as_server_user(&pg_bin().join("postgres"))
            .arg("-D")
            .arg(&self.data)
            .args(["-p", &self.port.to_string(), "-k"])
            .arg(&self.data)
            .args(["-c", "listen_addresses=127.0.0.1", "-c", "fsync=off"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("postgres");
        self.child = Some(child);
        let start = Instant::now();
        while std::net::TcpStream::connect(("127.0.0.1", self.port)).is_err() {
            assert!(
                start.elapsed() < Duration::from_secs(30),
                "the server did not start"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        // Accepting TCP comes a moment before accepting sessions.
        std::thread::sleep(Duration::from_millis(300));
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        if let Some(mut c) = self.child.take() {
            // SIGINT to the server itself (runuser passes no signal on): its fast shutdown.
            let pid = std::fs::read_to_string(self.data.join("postmaster.pid"))
                .ok()
                .and_then(|t| t.lines().next().map(|l| l.trim().to_string()))
                .unwrap_or_else(|| c.id().to_string());
            let _ = Command::new("kill").args(["-INT", &pid]).status();
            let start = Instant::now();
            while c.try_wait().ok().flatten().is_none() {
                if start.elapsed() > Duration::from_secs(20) {
                    let _ = c.kill();
                    break;
                }
                std::thread::sleep(Duration::from_millis(50));
            }
            let _ = c.wait();
        }
    }
}

/// A sandbox session's folder and `n` copies of it under new ids (`prefix` + number).
fn sessions(d: &Path, prefix: &str, n: usize) -> Vec<PathBuf> {
    let out = d.join("out");
    if !out.join("report.json").exists() {
        run_sandbox(&out, &[]);
    }
    let r = report(&out);
    (0..n)
        .map(|k| {
            let c = d.join(format!("{prefix}{k:03}"));
            std::fs::create_dir_all(&c).expect("dir");
            let mut rep = r.clone();
            rep["session_id"] = format!("{prefix}{k:013}").into();
            std::fs::write(c.join("report.json"), rep.to_string()).expect("report");
            std::fs::copy(out.join("input.vtrace"), c.join("input.vtrace")).expect("rec");
            c
        })
        .collect()
}

#[test]
fn eight_stations_store_at_once_and_nothing_is_lost_or_doubled() {
    let d = tmp("records_postgres", "stations");
    let mut server = Server::init(&d);
    server.start();
    let url = server.url();
    let own = sessions(&d, "s", 48);
    let shared = sessions(&d, "x", 1);
    // Eight stations, six sessions each plus the one all of them store, all at once on a
    // fresh server (the first ones to connect migrate the schema, one after the other).
    let stations: Vec<Child> = (0..8)
        .map(|k| {
            bin()
                .args([
                    "records",
                    "import",
                    "--trainee",
                    &format!("station-{k}"),
                    "--db",
                    &url,
                ])
                .args(&own[6 * k..6 * k + 6])
                .args(&shared)
                .stdout(Stdio::null())
                .stderr(Stdio::piped())
                .spawn()
                .expect("spawns")
        })
        .collect();
    for s in stations {
        let o = s.wait_with_output().expect("station");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let mut db = Db::open(Path::new(&url)).expect("connects");
    assert_eq!(db.version().expect("version"), 2);
    let rows = db.sessions(None).expect("sessions");
    assert_eq!(rows.len(), 49, "48 own sessions and the shared one");
    let mut ids: Vec<&str> = rows.iter().map(|r| r.session_id.as_str()).collect();
    ids.sort_unstable();
    ids.dedup();
    assert_eq!(ids.len(), 49, "a session doubled");
    for r in &rows {
        let s = db.session(&r.session_id).expect("query").expect("listed");
        let want = s.report["assessment"]["nodes"]
            .as_array()
            .map_or(0, Vec::len);
        assert_eq!(s.nodes.len(), want, "{} is partial", r.session_id);
    }
    let trainees = db.trainees().expect("trainees");
    assert_eq!(trainees.len(), 8);
    assert_eq!(trainees.iter().map(|t| t.sessions).sum::<u64>(), 49);
    let levels = db.level_distribution(None).expect("levels");
    assert_eq!(levels.iter().map(|(_, n)| n).sum::<u64>(), 8);
    // The command line reads the server too.
    let list = ok(&bin()
        .args(["records", "list", "--json", "--db", &url])
        .output()
        .expect("runs"));
    assert_eq!(list.lines().count(), 49);
}

#[test]
fn a_station_waits_for_the_server_and_an_unreachable_one_keeps_the_session() {
    let d = tmp("records_postgres", "retry");
    let mut server = Server::init(&d);
    let url = server.url();
    let dirs = sessions(&d, "r", 2);
    // Not started yet: the import tries again with back-off until the server comes.
    let waiting = bin()
        .args(["records", "import", "--trainee", "early", "--db", &url])
        .arg(&dirs[0])
        .env("VESALIUS_RECORDS_RETRY_S", "30")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawns");
    std::thread::sleep(Duration::from_millis(1500));
    server.start();
    let o = waiting.wait_with_output().expect("import");
    let said = ok(&o);
    assert!(said.contains("stored session r0000000000000"), "{said}");

    // A session whose records cannot be reached is kept and listed, and synced later.
    let spool = d.join("spool.txt");
    let dead = format!("postgres://vesalius@127.0.0.1:{}/postgres", free_port());
    let trace = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/traces/sandbox-demo.toml");
    let o = bin()
        .args(["run", "sandbox", "--headless", "--trace"])
        .arg(&trace)
        .arg("--out")
        .arg(d.join("late"))
        .args(["--records", &dead, "--trainee", "late"])
        .env("VESALIUS_RECORDS_RETRY_S", "0.5")
        .env("VESALIUS_SPOOL", &spool)
        .output()
        .expect("runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("records sync"), "{err}");
    let listed = std::fs::read_to_string(&spool).expect("spool");
    assert_eq!(listed.lines().count(), 1, "{listed}");
    let said = ok(&bin()
        .args(["records", "sync", "--db", &url])
        .env("VESALIUS_SPOOL", &spool)
        .output()
        .expect("runs"));
    assert!(said.contains("1 stored, 0 still listed"), "{said}");
    assert_eq!(std::fs::read_to_string(&spool).expect("spool"), "");
    let mut db = Db::open(Path::new(&url)).expect("connects");
    let late = report(&d.join("late"));
    let id = late["session_id"].as_str().unwrap_or("?");
    assert_eq!(
        db.sessions(Some("late")).expect("sessions")[0].session_id,
        id
    );
    assert_eq!(db.sessions(Some("early")).expect("sessions").len(), 1);
}

#[test]
fn calibrating_from_a_server_gives_what_a_file_gives() {
    // Ten copies of the sandbox demo's session under two groups, their completion times and
    // paths spread apart (experts 8-12 s and 0.2-0.24 m, novices 30-50 s and 0.8-1.2 m),
    // stored in a server and in a file: the same validation table and calibrated tree.
    let d = tmp("records_postgres", "calibrate");
    let mut server = Server::init(&d);
    server.start();
    let url = server.url();
    let file = d.join("records.sqlite");
    let dirs = sessions(&d, "c", 10);
    for (k, dir) in dirs.iter().enumerate() {
        let mut r = report(dir);
        let expert = k < 5;
        let j = (k % 5) as f64;
        r["metrics"]["completion_time_s"] = (if expert { 8.0 + j } else { 30.0 + 5.0 * j }).into();
        r["motion"]["path_m"] = (if expert {
            0.2 + 0.01 * j
        } else {
            0.8 + 0.1 * j
        })
        .into();
        std::fs::write(dir.join("report.json"), r.to_string()).expect("report");
    }
    for db in [url.as_str(), file.to_str().expect("path")] {
        for (who, group, range) in [("e", "experts", 0..5), ("n", "novices", 5..10)] {
            ok(&bin()
                .args(["records", "trainee", who, "--group", group, "--db", db])
                .output()
                .expect("trainee"));
            ok(&bin()
                .args(["records", "import", "--trainee", who, "--db", db])
                .args(&dirs[range])
                .output()
                .expect("import"));
        }
    }
    let calibrate = |db: &str, out: &Path| {
        ok(&bin()
            .args([
                "records",
                "calibrate",
                "--tree",
                "sandbox",
                "--expert",
                "experts",
                "--novice",
                "novices",
                "--json",
                "--db",
                db,
                "--out",
            ])
            .arg(out)
            .output()
            .expect("calibrate"))
    };
    let (a, b) = (
        calibrate(&url, &d.join("a.toml")),
        calibrate(file.to_str().expect("path"), &d.join("b.toml")),
    );
    let table: serde_json::Value = serde_json::from_str(
        a.lines()
            .take_while(|l| !l.starts_with("calibrated tree"))
            .collect::<Vec<_>>()
            .join("\n")
            .as_str(),
    )
    .expect("JSON table");
    assert_eq!(
        a,
        b.replace(
            &*d.join("b.toml").to_string_lossy(),
            &d.join("a.toml").to_string_lossy()
        )
    );
    let time = table["rows"]
        .as_array()
        .expect("rows")
        .iter()
        .find(|r| r["metric"] == "completion_time_s")
        .expect("the time's row");
    // Medians 10 s and 40 s; every expert faster: U = 0, exact p = 2 / 252.
    assert_eq!(time["now"], serde_json::json!([10.0, 40.0]));
    assert_eq!(time["test"]["u"], 0.0);
    assert!((time["test"]["p"].as_f64().expect("p") - 2.0 / 252.0).abs() < 1e-12);
    assert_eq!(
        std::fs::read_to_string(d.join("a.toml")).expect("a"),
        std::fs::read_to_string(d.join("b.toml")).expect("b")
    );
}
