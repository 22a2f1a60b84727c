//! The web front probed as an attacker and a careless user would, over loopback only, every
//! loop bounded in count and time: another site's page (a rebound host name, a foreign origin,
//! a WebSocket from elsewhere), slow clients, header floods, links and FIFOs in the project; and
//! the studio's job through races, a killed studio and a wrong disc size. Assertions are on
//! statuses, kinds and the job's fields.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::time::{Duration, Instant};

use scanner_tests::StudioProcess;
use scanner_tests::page::{addr_of, get, post, raw, state, wait};

/// Peak and current resident memory of a process, kB (`VmHWM`, `VmRSS`).
fn memory_kb(pid: u32) -> (u64, u64) {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    let field = |name: &str| {
        status
            .lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|v| v.parse().ok())
            .unwrap()
    };
    (field("VmHWM:"), field("VmRSS:"))
}

/// The turntable part on its disc at 640×480 (the disc printed on A4), `frames` a sweep, and
/// the rig's true calibration beside it: the head needs no calibration shots.
fn turntable_job(dir: &Path, frames: u32) {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scanner-device/scenes/turntable.toml"
    ))
    .unwrap()
    .replace("width = 1280", "width = 640")
    .replace("height = 960", "height = 480")
    .replace("frames = 300", &format!("frames = {frames}"));
    std::fs::write(dir.join("job.toml"), &text).unwrap();
    let rig = scanner_rig::Rig::new(scanner_rig::Scene::from_toml_in(&text, dir).unwrap()).unwrap();
    rig.truth_calibration()
        .save(&dir.join("calibration.toml"))
        .unwrap();
}

fn start_studio(dir: &Path) -> StudioProcess {
    StudioProcess::on_rig(dir, "--scene job.toml --calibration calibration.toml")
}

#[test]
fn other_sites_slow_clients_floods_links_and_fifos_get_the_fronts_refusals() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    turntable_job(dir, 60);
    let studio = start_studio(dir);
    let addr = addr_of(&studio.url);
    let port = addr.rsplit(':').next().unwrap().to_string();
    assert_eq!(get(&addr, "/api/state").0, 200);

    // Another site's page: a rebound name, its origin, another local site's origin.
    let as_host = |host: &str, req: &str| raw(&addr, &req.replace("HOST", host));
    let (code, v) = as_host(
        &format!("evil.example:{port}"),
        "GET /api/state HTTP/1.1\r\nHost: HOST\r\nConnection: close\r\n\r\n",
    );
    assert_eq!((code, v["refused"].as_str()), (421, Some("foreign_host")));
    let laser_off = r#"{"command":"laser","on":false}"#;
    let (code, v) = as_host(
        &format!("evil.example:{port}"),
        &format!(
            "POST /api/command HTTP/1.1\r\nHost: HOST\r\nOrigin: http://HOST\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{laser_off}",
            laser_off.len()
        ),
    );
    assert_eq!((code, v["refused"].as_str()), (421, Some("foreign_host")));
    for origin in ["http://evil.example", "http://127.0.0.1:1", "null"] {
        let (code, v) = raw(
            &addr,
            &format!(
                "POST /api/command HTTP/1.1\r\nHost: HOST\r\nOrigin: {origin}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{laser_off}",
                laser_off.len()
            ),
        );
        assert_eq!(
            (code, v["refused"].as_str()),
            (403, Some("foreign_origin")),
            "{origin}"
        );
    }
    let (code, v) = raw(
        &addr,
        "GET /api/state HTTP/1.1\r\nConnection: close\r\n\r\n",
    );
    assert_eq!(
        (code, v["refused"].as_str()),
        (421, Some("foreign_host")),
        "no Host"
    );
    // the page's own requests are answered
    assert_eq!(post(&addr, "/api/command", r#"{"command":"hello"}"#).0, 200);
    let (code, v) = raw(
        &addr,
        "POST /api/command HTTP/1.1\r\nHost: HOST\r\nContent-Type: text/plain\r\nContent-Length: 19\r\nConnection: close\r\n\r\n{\"command\":\"hello\"}",
    );
    assert_eq!(
        (code, v["refused"].as_str()),
        (415, Some("not_json")),
        "a form's post"
    );

    // Slow clients: 50 that send a byte a second hold no thread and lock nobody out, and each
    // is closed at the head's deadline although it keeps sending.
    let slow: Vec<_> = (0..50)
        .map(|_| {
            let addr = addr.clone();
            std::thread::spawn(move || {
                let mut s = TcpStream::connect(&addr).unwrap();
                s.set_write_timeout(Some(Duration::from_secs(2))).unwrap();
                let t0 = Instant::now();
                let _ = s.write_all(b"GET / HTTP/1.1\r\nX-Slow: ");
                while t0.elapsed() < Duration::from_secs(20) {
                    if s.write_all(b"a").is_err() {
                        break;
                    }
                    std::thread::sleep(Duration::from_millis(1000));
                }
                t0.elapsed()
            })
        })
        .collect();
    std::thread::sleep(Duration::from_millis(1500));
    let mut worst = Duration::ZERO;
    for _ in 0..5 {
        let t0 = Instant::now();
        assert_eq!(
            get(&addr, "/api/state").0,
            200,
            "the page answers during the flood"
        );
        worst = worst.max(t0.elapsed());
        std::thread::sleep(Duration::from_millis(200));
    }
    let held: Vec<Duration> = slow.into_iter().map(|t| t.join().unwrap()).collect();
    let longest = held.iter().max().unwrap();
    eprintln!(
        "slow clients: the page answered in at most {:.0} ms during the flood; a slow client was held at most {:.1} s",
        worst.as_secs_f64() * 1000.0,
        longest.as_secs_f64()
    );
    assert!(
        *longest < Duration::from_secs(15),
        "a client sending a byte a second is closed at the head's deadline, not kept: {longest:?}"
    );

    // Header floods: one 100 MB header value, then 2 million header lines.
    let flood = |chunk: &[u8], total: usize| -> (u16, usize) {
        let mut s = TcpStream::connect(&addr).unwrap();
        s.set_write_timeout(Some(Duration::from_secs(5))).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        let _ = s.write_all(format!("GET /api/state HTTP/1.1\r\nHost: {addr}\r\n").as_bytes());
        let mut sent = 0;
        while sent < total {
            match s.write(chunk) {
                Ok(n) => sent += n,
                Err(_) => break,
            }
        }
        let mut answer = Vec::new();
        let _ = s.read_to_end(&mut answer);
        let code = String::from_utf8_lossy(&answer)
            .get(9..12)
            .and_then(|c| c.parse().ok())
            .unwrap_or(0);
        (code, sent)
    };
    let big = [b'a'; 65536];
    let mut value = b"X-Big: ".to_vec();
    value.extend_from_slice(&big);
    let (code, sent) = flood(&value, 100 << 20);
    assert!(code == 431 || code == 0, "a 100 MB header: {code}");
    let lines = b"X-Line: b\r\n".repeat(4096);
    let (code2, sent2) = flood(&lines, 2_000_000 * 11);
    assert!(
        code2 == 431 || code2 == 0,
        "2 million header lines: {code2}"
    );
    let (peak, now) = memory_kb(studio.pid());
    eprintln!(
        "header floods: {:.1} MB and {:.1} MB sent before the server closed ({code}, {code2}); the studio's memory peak {:.1} MB, {:.1} MB in use after",
        sent as f64 / 1e6,
        sent2 as f64 / 1e6,
        peak as f64 / 1024.0,
        now as f64 / 1024.0
    );
    assert!(
        sent < 100 << 20,
        "the server stopped reading the 100 MB header"
    );
    assert!(peak < 64 << 10, "memory stays under 64 MB: {peak} kB");
    assert_eq!(get(&addr, "/api/state").0, 200);

    // Links and FIFOs in the project folder are not served, and do not hold the server.
    let model = dir.join("project/model");
    std::fs::create_dir_all(&model).unwrap();
    std::fs::write(dir.join("secret.txt"), "not the project's").unwrap();
    std::os::unix::fs::symlink(dir.join("secret.txt"), model.join("model.obj")).unwrap();
    assert!(
        std::process::Command::new("mkfifo")
            .arg(model.join("model.stl"))
            .status()
            .unwrap()
            .success()
    );
    let (code, v) = get(&addr, "/files/model.obj");
    assert_eq!((code, v["refused"].as_str()), (403, Some("link")));
    let (code, v) = get(&addr, "/files/model.stl");
    assert_eq!((code, v["refused"].as_str()), (403, Some("not_regular")));
    let (code, v) = get(&addr, "/api/model.stl");
    assert_eq!((code, v["refused"].as_str()), (404, Some("not_regular")));
    assert_eq!(get(&addr, "/api/state").0, 200, "the FIFO holds no thread");
    std::fs::remove_dir_all(&model).unwrap();
    std::os::unix::fs::symlink(dir, &model).unwrap();
    std::fs::write(dir.join("model.3mf"), "outside").unwrap();
    let (code, v) = get(&addr, "/files/model.3mf");
    assert_eq!(
        (code, v["refused"].as_str()),
        (403, Some("link")),
        "a linked folder"
    );
}

#[test]
fn the_live_view_answers_only_its_own_hosts_and_its_own_pages_streams() {
    let v = scanner_web::live::LiveView::start("127.0.0.1:0".parse().unwrap(), &[]).unwrap();
    let addr = addr_of(v.url());
    let port = addr.rsplit(':').next().unwrap().to_string();
    assert_eq!(get(&addr, "/").0, 200);
    let (code, body) = raw(
        &addr,
        &format!("GET / HTTP/1.1\r\nHost: evil.example:{port}\r\nConnection: close\r\n\r\n"),
    );
    assert_eq!(
        (code, body["refused"].as_str()),
        (421, Some("foreign_host"))
    );
    let upgrade = |origin: &str| {
        let mut s = TcpStream::connect(&addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        write!(
            s,
            "GET /live HTTP/1.1\r\nHost: {addr}\r\nOrigin: {origin}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n"
        )
        .unwrap();
        let mut buf = [0u8; 12];
        s.read_exact(&mut buf).map_or(0, |()| {
            String::from_utf8_lossy(&buf[9..12]).parse().unwrap_or(0)
        })
    };
    assert_eq!(upgrade("http://evil.example"), 403, "another site's page");
    assert_eq!(
        upgrade(&format!("http://127.0.0.1:{}", 1)),
        403,
        "another local site"
    );
    assert_eq!(
        upgrade(&format!("http://{addr}")),
        101,
        "the page's own stream"
    );
    assert_eq!(upgrade(&format!("http://localhost:{port}")), 101);
}

/// Sweeps asked for twice at once make one view; a studio killed in the middle of a sweep is
/// started again with that view rebuilt from its journal, and the merge takes it.
#[test]
fn no_view_is_lost_to_a_race_or_a_killed_studio() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    turntable_job(dir, 240);
    let studio = start_studio(dir);
    let addr = addr_of(&studio.url);
    let sweep = r#"{"command":"sweep","disc":1}"#;
    // the scene's views 0, 2 and 4 (0°, 118°, 236° on the disc), each asked for twice at once
    for round in 0..3 {
        if round > 0 {
            assert_eq!(
                post(&addr, "/api/command", r#"{"command":"turn","steps":2}"#).1["outcome"],
                "accepted"
            );
        }
        let both: Vec<_> = (0..2)
            .map(|_| {
                let addr = addr.clone();
                std::thread::spawn(move || post(&addr, "/api/command", sweep))
            })
            .collect();
        let answers: Vec<(u16, serde_json::Value)> =
            both.into_iter().map(|t| t.join().unwrap()).collect();
        let accepted = answers
            .iter()
            .filter(|(_, v)| v["outcome"] == "accepted")
            .count();
        assert_eq!(accepted, 1, "one of two sweeps at once: {answers:?}");
        assert!(
            answers.iter().any(|(_, v)| v["outcome"] == "busy"),
            "{answers:?}"
        );
        wait(&addr, 120, "the view ends", |s| {
            s["views"]
                .as_array()
                .is_some_and(|v| v.len() == round + 1 && v.iter().all(|x| x["done"] == true))
        });
    }
    assert_eq!(state(&addr)["views"].as_array().unwrap().len(), 3);

    // a fourth view (the scene's view 5, 301°), cut by SIGKILL in its middle
    assert_eq!(
        post(&addr, "/api/command", r#"{"command":"turn","steps":1}"#).1["outcome"],
        "accepted"
    );
    assert_eq!(post(&addr, "/api/command", sweep).1["outcome"], "accepted");
    wait(&addr, 60, "points arrive", |s| {
        s["views"][3]["points"].as_u64().unwrap_or(0) > 2000
    });
    let seen = state(&addr)["views"][3]["points"].as_u64().unwrap();
    studio.kill();
    let again = start_studio(dir);
    let addr = addr_of(&again.url);
    let s = state(&addr);
    let view = &s["views"][3];
    assert_eq!(view["rebuilt"], true, "{view}");
    assert_eq!(view["done"], true);
    let points = view["points"].as_u64().unwrap();
    assert!(
        points >= seen,
        "the journal's points: {seen} seen, {points} rebuilt"
    );
    eprintln!("the cut view: {seen} points seen before SIGKILL, {points} rebuilt from its journal");
    // the merge takes it
    let (code, v) = post(&addr, "/api/merge", r#"{"min_overlap":0.4}"#);
    assert_eq!(code, 202, "{v}");
    wait(&addr, 600, "the merge", |s| {
        !s["merge"].is_null() && s["merge"]["state"] != "running"
    });
    let m = state(&addr)["merge"].clone();
    assert_eq!(m["left_out"].as_array().map(Vec::len), Some(0), "{m}");
    assert_eq!(
        m["report"]["views"].as_array().map(Vec::len),
        Some(4),
        "{m}"
    );
    assert_eq!(m["state"], "merged", "{m}");
    let scale = m["report"]["disc_scale"]
        .as_f64()
        .expect("the disc measured");
    eprintln!(
        "the disc measured by the laser at {:.2} % of the A4 disc's size",
        100.0 * scale
    );
    assert!((scale - 1.0).abs() < 0.03, "{scale}");
}

/// The disc printed on A4 and chosen as A3 on the page: refused with the size the laser
/// measured named, before anything says merged.
#[test]
fn a_wrong_disc_size_is_refused_with_the_measured_size() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    turntable_job(dir, 120);
    let studio = start_studio(dir);
    let addr = addr_of(&studio.url);
    for round in 0..2 {
        if round > 0 {
            post(&addr, "/api/command", r#"{"command":"turn","steps":2}"#);
        }
        assert_eq!(
            post(&addr, "/api/command", r#"{"command":"sweep","disc":2}"#).1["outcome"],
            "accepted"
        );
        wait(&addr, 120, "the view ends", |s| {
            s["views"]
                .as_array()
                .is_some_and(|v| v.len() == round + 1 && v.iter().all(|x| x["done"] == true))
        });
    }
    assert_eq!(state(&addr)["views"][0]["disc"], "found");
    let (code, _) = post(&addr, "/api/merge", r#"{"min_overlap":0.4}"#);
    assert_eq!(code, 202);
    wait(&addr, 600, "the merge", |s| {
        !s["merge"].is_null() && s["merge"]["state"] != "running"
    });
    let m = state(&addr)["merge"].clone();
    assert_eq!(m["state"], "refused", "{m}");
    assert_eq!(m["report"]["refused"]["check"], "disc_size", "{m}");
    let problem = m["problems"]
        .as_array()
        .and_then(|p| p.iter().find(|p| p["kind"] == "disc_size"))
        .unwrap_or_else(|| panic!("a disc_size problem: {m}"));
    let scale = m["report"]["disc_scale"].as_f64().unwrap();
    // the A4 disc (190 mm) measured against the A3 one chosen (277 mm)
    let measured = scale * 277.0;
    eprintln!("{}", problem["words"]);
    assert!((measured - 190.0).abs() < 6.0, "measured {measured:.1} mm");
    assert!(
        problem["words"]
            .as_str()
            .unwrap()
            .contains(&format!("{measured:.0} mm")),
        "the measured size is named: {problem}"
    );
    assert!(!dir.join("project/model/model.3mf").exists());
}
