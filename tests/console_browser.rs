//! The operator console in a real browser against a real stack: Debian's chromium, driven by
//! chromedriver over WebDriver (both installed by `.ci/run`; nothing downloads a browser). The
//! stack runs in a private domain; what the page shows (pushed over its one push connection,
//! nothing polled) and what the clicks do (commands, the e-stop, an operator mark) are checked
//! on the channels. Also prints the console's figures for docs/benchmarks.md (CPU share of one core
//! at the default view rate, capture-to-browser latency of the camera view, e-stop click to arms
//! braked); nothing is asserted about them.

mod common;

use common::console::{control_token, wait_for_harvesting_console, wait_until};
use common::webdriver::{Browser, free_port};
use common::{
    TempDir, leftover_files, one_stack_at_a_time, spawn_harvest, unique_domain, wait_with_watchdog,
};
use harvest_bench::stats::percentile;
use harvest_ipc::catalogue::{
    ARM_COMMAND, ARM_STATE, EMERGENCY_STOP, HARVEST_EVENTS, OPERATOR_MARK, OPERATOR_MODE,
    PROCESS_HEALTH, VACUUM_STATE,
};
use harvest_ipc::payloads::{ArmPhase, HarvestEventKind, OperatorModeCode};
use harvest_ipc::{Context, Domain, MonotonicClock, Subscriber};
use serde_json::{Value, json};
use std::time::{Duration, Instant};

fn latest<T: harvest_ipc::Payload + Copy>(subscriber: &Subscriber<T>, slot: &mut Option<T>) {
    while let Ok(Some(sample)) = subscriber.receive() {
        *slot = Some(*sample);
    }
}

fn page_text(browser: &Browser, id: &str) -> String {
    browser
        .execute(
            "return document.getElementById(arguments[0]).textContent;",
            json!([id]),
        )
        .as_str()
        .unwrap_or_default()
        .to_owned()
}

/// A cheap hash of the camera image as the page shows it, with the number of views shown.
fn camera_hash(browser: &Browser) -> (u64, u64) {
    let value = browser.execute(
        "const img = document.getElementById('camera');
         if (!img.naturalWidth) return [0, 0];
         const c = document.createElement('canvas');
         c.width = img.naturalWidth; c.height = img.naturalHeight;
         const g = c.getContext('2d'); g.drawImage(img, 0, 0);
         const d = g.getImageData(0, 0, c.width, c.height).data;
         let h = 0; for (let i = 0; i < d.length; i += 7) { h = (h * 31 + d[i]) >>> 0; }
         return [window.consoleStats.views, h];",
        json!([]),
    );
    (
        value[0].as_u64().unwrap_or(0),
        value[1].as_u64().unwrap_or(0),
    )
}

#[test]
fn the_console_page_watches_and_controls_the_robot() {
    assert!(
        std::path::Path::new("/usr/bin/chromium").exists(),
        "the browser test needs Debian's chromium and chromium-driver (.ci/run installs them)"
    );
    let _stack = one_stack_at_a_time();
    let domain = unique_domain("console");
    let port = free_port();
    let dir = TempDir::new("console");
    let launch = dir.write(
        "console.toml",
        &format!(
            r#"
[stack]
startup_grace_ms = 15000
[[process]]
name = "sim"
command = "sim"
args = ["--scenario", "default", "--seed", "1", "--camera-rate-hz", "15"]
[[process]]
name = "camera"
command = "camera"
[[process]]
name = "perception"
command = "perception"
args = ["--calibration", "{calibration}"]
[[process]]
name = "arm1"
command = "arm"
args = ["--id", "1"]
[[process]]
name = "arm2"
command = "arm"
args = ["--id", "2"]
[[process]]
name = "vacuum"
command = "vacuum"
[[process]]
name = "executive"
command = "executive"
args = ["--initial-mode", "harvesting"]
[[process]]
name = "console"
command = "console"
args = ["--listen", "127.0.0.1:{port}"]
restart = "on-failure"
"#,
            calibration = common::SIM_CAMERA_CALIBRATION,
        ),
    );
    let stack = spawn_harvest(
        &domain,
        &["up", "--launch", launch.to_str().expect("utf-8")],
    );
    let token = control_token(&domain);
    wait_for_harvesting_console(port);

    let ipc_domain = Domain::new(&domain).expect("domain");
    let context = Context::new(&ipc_domain, "console-test").expect("context");
    let mode_in = context.subscriber(OPERATOR_MODE).expect("mode");
    let arms_in = [0, 1].map(|i| context.subscriber(ARM_STATE[i]).expect("arm state"));
    let commands_in = [0, 1].map(|i| {
        context
            .subscriber_with_buffer(ARM_COMMAND[i], 256)
            .expect("arm command")
    });
    let vacuum_in = context.subscriber(VACUUM_STATE).expect("vacuum");
    let estop_in = context.subscriber(EMERGENCY_STOP).expect("estop");
    let events_in = context
        .subscriber_with_buffer(HARVEST_EVENTS, 256)
        .expect("events");
    let health_in = context
        .subscriber_with_buffer(PROCESS_HEALTH, 256)
        .expect("health");
    let marks_in = context
        .subscriber_with_buffer(OPERATOR_MARK, 16)
        .expect("marks");
    let mut mode = None;
    let mut arms = [None, None];
    let mut vacuum = None;
    let mut estop = None;
    let refresh = |mode: &mut Option<_>, arms: &mut [Option<_>; 2], vacuum: &mut Option<_>| {
        latest(&mode_in, mode);
        latest(&arms_in[0], &mut arms[0]);
        latest(&arms_in[1], &mut arms[1]);
        latest(&vacuum_in, vacuum);
    };

    let browser = Browser::start((1700, 1050));
    browser.navigate(&format!("http://127.0.0.1:{port}/"));

    // The camera image changes over time.
    wait_until(
        "three camera views in the page",
        Duration::from_secs(30),
        || camera_hash(&browser).0 >= 3,
    );
    let (views, first_hash) = camera_hash(&browser);
    println!(
        "page errors so far: {}",
        browser.execute("return window.consoleStats.errors;", json!([]))
    );
    wait_until("the camera image changing", Duration::from_secs(30), || {
        let (now_views, hash) = camera_hash(&browser);
        now_views > views && hash != first_hash
    });
    // Pushed, not polled: the status and the views came over the page's one push connection,
    // and the page fetched nothing from the API.
    let pushed = browser.execute(
        "return [window.consoleStats.liveOpens, window.consoleStats.statuses,
                 performance.getEntriesByType('resource').filter(e => e.name.includes('/api/')).map(e => e.name)];",
        json!([]),
    );
    assert_eq!(pushed[0], json!(1), "one push connection: {pushed}");
    assert!(
        pushed[1].as_u64().unwrap_or(0) > 0,
        "no status pushed: {pushed}"
    );
    assert_eq!(pushed[2], json!([]), "the page polled the API: {pushed}");

    // The mark button: an operator mark on operator/mark, from the console, with the text.
    browser.type_into("#mark-text", "apple 7 dropped at the bin");
    browser.click("#btn-mark");
    let mut mark = None;
    wait_until("the mark on operator/mark", Duration::from_secs(10), || {
        while let Ok(Some(sample)) = marks_in.receive() {
            mark = Some(*sample);
        }
        mark.is_some()
    });
    let mark: harvest_ipc::payloads::OperatorMark = mark.expect("mark");
    assert_eq!(mark.text.as_str(), "apple 7 dropped at the bin");
    assert!(
        mark.source.as_str().starts_with("console "),
        "{:?}",
        mark.source.as_str()
    );
    wait_until(
        "the mark's answer on the page",
        Duration::from_secs(5),
        || page_text(&browser, "mark-answer").starts_with("marked"),
    );

    // Status values match the channels.
    wait_until(
        "the page's mode, harvested counts and valves matching the channels",
        Duration::from_secs(15),
        || {
            refresh(&mut mode, &mut arms, &mut vacuum);
            let (Some(m), [Some(a1), Some(a2)], Some(v)) = (mode, arms, vacuum) else {
                return false;
            };
            let m: harvest_ipc::payloads::OperatorModeState = m;
            let (a1, a2): (
                harvest_ipc::payloads::ArmState,
                harvest_ipc::payloads::ArmState,
            ) = (a1, a2);
            let v: harvest_ipc::payloads::VacuumState = v;
            let valves = browser.execute(
                "return [1,2,3,4].map(k => document.getElementById('valve' + k).dataset.open);",
                json!([]),
            );
            let valves_match = (0..4).all(|k| valves[k] == json!(v.valve_open[k].to_string()));
            page_text(&browser, "mode-name") == m.mode_code().map_or("?", OperatorModeCode::name)
                && page_text(&browser, "arm1-harvested") == a1.harvested_count.to_string()
                && page_text(&browser, "arm2-harvested") == a2.harvested_count.to_string()
                && valves_match
        },
    );

    // A wrong token is refused, on the page, and changes nothing.
    browser.type_into("#token", "0123456789abcdef0123456789abcdef");
    browser.click("#take-control");
    wait_until(
        "the wrong token's refusal on the page",
        Duration::from_secs(10),
        || {
            let answer = page_text(&browser, "last-answer");
            answer.contains("REFUSED") && answer.contains("wrong control token")
        },
    );
    browser.click("button[data-command=pause]");
    wait_until(
        "the refused pause on the page",
        Duration::from_secs(10),
        || page_text(&browser, "last-answer").starts_with("pause: REFUSED"),
    );
    refresh(&mut mode, &mut arms, &mut vacuum);
    assert_eq!(
        mode.and_then(|m: harvest_ipc::payloads::OperatorModeState| m.mode_code()),
        Some(OperatorModeCode::Harvesting)
    );

    // The right token: the page takes control.
    browser.type_into("#token", &token);
    browser.click("#take-control");
    wait_until("the page in control", Duration::from_secs(10), || {
        page_text(&browser, "control-status").starts_with("in control")
    });

    // "Next stop": enabled while harvesting; this stack has no row, so the executive's refusal
    // (over the real command channel) comes back to the page.
    let next_stop_disabled = |browser: &Browser| {
        browser.execute(
            "return document.getElementById('btn-next-stop').disabled;",
            json!([]),
        )
    };
    assert_eq!(next_stop_disabled(&browser), json!(false));
    browser.click("#btn-next-stop");
    wait_until(
        "the executive's answer to next-stop on the page",
        Duration::from_secs(10),
        || {
            let answer = page_text(&browser, "last-answer");
            answer.starts_with("next-stop: REFUSED") && answer.contains("no row configured")
        },
    );

    // Pause: the mode changes and no arm starts a new approach.
    browser.click("button[data-command=pause]");
    wait_until(
        "mode paused on operator/mode",
        Duration::from_secs(10),
        || {
            refresh(&mut mode, &mut arms, &mut vacuum);
            mode.and_then(|m: harvest_ipc::payloads::OperatorModeState| m.mode_code())
                == Some(OperatorModeCode::Paused)
        },
    );
    wait_until(
        "next-stop disabled on the page while paused",
        Duration::from_secs(5),
        || next_stop_disabled(&browser) == json!(true),
    );
    let paused_ns = MonotonicClock::read_ns();
    let idle = |arms: &[Option<harvest_ipc::payloads::ArmState>; 2]| {
        arms.iter()
            .all(|a| a.is_some_and(|a| a.phase == ArmPhase::Idle))
    };
    wait_until(
        "both arms idle after the pause",
        Duration::from_secs(30),
        || {
            refresh(&mut mode, &mut arms, &mut vacuum);
            idle(&arms)
        },
    );
    while let Ok(Some(_)) = events_in.receive() {}
    let watch_until = Instant::now() + Duration::from_secs(3);
    while Instant::now() < watch_until {
        refresh(&mut mode, &mut arms, &mut vacuum);
        assert!(idle(&arms), "an arm left idle while paused: {arms:?}");
        while let Ok(Some(event)) = events_in.receive() {
            assert!(
                !matches!(
                    event.kind.get(),
                    Ok(HarvestEventKind::Assigned | HarvestEventKind::TargetAccepted)
                ) || event.header.capture_ns < paused_ns,
                "a new apple was started while paused: {:?}",
                *event
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    }

    // Resume: the harvest goes on (an arm takes a new target).
    browser.click("button[data-command=resume]");
    wait_until(
        "an arm approaching after the resume",
        Duration::from_secs(40),
        || {
            refresh(&mut mode, &mut arms, &mut vacuum);
            arms.iter()
                .any(|a| a.is_some_and(|a| a.phase == ArmPhase::Approach))
        },
    );
    wait_until("harvesting on the page", Duration::from_secs(5), || {
        page_text(&browser, "mode-name") == "harvesting"
    });

    // The screenshot in the README (docs/console.png), while harvesting with overlays.
    std::thread::sleep(Duration::from_millis(600));
    let png = browser.screenshot();
    let target = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/console.png");
    std::fs::write(&target, &png).expect("write screenshot");
    if let Ok(path) = std::env::var("HARVEST_CONSOLE_SCREENSHOT") {
        std::fs::write(&path, &png).expect("write screenshot");
    }

    // E-stop: one click; the arms brake and the valves close (on the channels).
    for subscriber in &commands_in {
        while let Ok(Some(_)) = subscriber.receive() {}
    }
    browser.click("#btn-estop");
    let mut braked_ns: [Option<u64>; 2] = [None, None];
    wait_until(
        "the e-stop engaged, both arms braked and stopped, every valve closed",
        Duration::from_secs(10),
        || {
            refresh(&mut mode, &mut arms, &mut vacuum);
            latest(&estop_in, &mut estop);
            for (i, subscriber) in commands_in.iter().enumerate() {
                while let Ok(Some(command)) = subscriber.receive() {
                    if command.hold == 1 && braked_ns[i].is_none() {
                        braked_ns[i] = Some(command.header.capture_ns);
                    }
                }
            }
            let engaged =
                estop.is_some_and(|e: harvest_ipc::payloads::EmergencyStop| e.engaged == 1);
            let stopped = arms
                .iter()
                .all(|a| a.is_some_and(|a| a.phase == ArmPhase::Stopped));
            let closed =
                vacuum.is_some_and(|v: harvest_ipc::payloads::VacuumState| v.valve_open == [0; 4]);
            engaged && stopped && closed && braked_ns.iter().all(Option::is_some)
        },
    );
    wait_until("E-STOP ENGAGED on the page", Duration::from_secs(5), || {
        page_text(&browser, "estop-state") == "E-STOP ENGAGED"
    });
    let click_ns = browser.execute("return window.consoleStats.estopClickNs;", json!([]));
    let click_ns = click_ns.as_f64().unwrap_or(f64::NAN);
    let click_to_brake_ms = braked_ns.map(|ns| (ns.unwrap_or(0) as f64 - click_ns) / 1e6);

    // Release restores control: idle, then start harvesting again.
    browser.click("#btn-release");
    wait_until(
        "the e-stop released and the mode idle",
        Duration::from_secs(10),
        || {
            refresh(&mut mode, &mut arms, &mut vacuum);
            latest(&estop_in, &mut estop);
            estop.is_some_and(|e: harvest_ipc::payloads::EmergencyStop| e.engaged == 0)
                && mode.and_then(|m: harvest_ipc::payloads::OperatorModeState| m.mode_code())
                    == Some(OperatorModeCode::Idle)
        },
    );
    browser.click("button[data-command=start]");
    wait_until(
        "harvesting again after the release",
        Duration::from_secs(10),
        || {
            refresh(&mut mode, &mut arms, &mut vacuum);
            mode.and_then(|m: harvest_ipc::payloads::OperatorModeState| m.mode_code())
                == Some(OperatorModeCode::Harvesting)
                && arms
                    .iter()
                    .all(|a| a.is_some_and(|a| a.phase != ArmPhase::Stopped))
        },
    );

    // Figures: console CPU over 10 s with the page open, view latency.
    let mut console_pid = None;
    wait_until("the console's heartbeat", Duration::from_secs(5), || {
        while let Ok(Some(beat)) = health_in.receive() {
            if beat.process_name.as_str() == "console" {
                console_pid = Some(beat.pid);
            }
        }
        console_pid.is_some()
    });
    let console_pid = console_pid.expect("console pid");
    let cpu_seconds = |pid| harvest_bench::proc_cpu::cpu_time_s(pid).expect("console CPU time");
    let cpu_before = cpu_seconds(console_pid);
    let views_before = camera_hash(&browser).0;
    std::thread::sleep(Duration::from_secs(10));
    let cpu_share = (cpu_seconds(console_pid) - cpu_before) / 10.0;
    let view_rate_hz = (camera_hash(&browser).0 - views_before) as f64 / 10.0;
    let latencies = browser.execute("return window.consoleStats.latenciesMs;", json!([]));
    let mut latencies: Vec<f64> = latencies
        .as_array()
        .map(|a| a.iter().filter_map(Value::as_f64).collect())
        .unwrap_or_default();
    let (p50_ms, p99_ms) = (
        percentile(&mut latencies, 0.5),
        percentile(&mut latencies, 0.99),
    );
    println!(
        "console figures: CPU {:.1} % of one core at {view_rate_hz:.1} views/s shown; \
capture-to-browser latency p50 {:.1} ms, p99 {:.1} ms over {} views; e-stop click to arm 1 \
braked {:.1} ms, arm 2 {:.1} ms",
        cpu_share * 100.0,
        p50_ms,
        p99_ms,
        latencies.len(),
        click_to_brake_ms[0],
        click_to_brake_ms[1],
    );

    // kill -9 of the console changes nothing for the arms.
    drop(browser);
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(console_pid as i32),
        nix::sys::signal::Signal::SIGKILL,
    )
    .expect("kill the console");
    let mut states_seen = [0u32; 2];
    let watch_until = Instant::now() + Duration::from_secs(3);
    while Instant::now() < watch_until {
        while let Ok(Some(sample)) = mode_in.receive() {
            assert_eq!(sample.mode_code(), Some(OperatorModeCode::Harvesting));
        }
        while let Ok(Some(sample)) = estop_in.receive() {
            assert_eq!(sample.engaged, 0, "an e-stop after the console died");
        }
        for (i, subscriber) in arms_in.iter().enumerate() {
            while let Ok(Some(state)) = subscriber.receive() {
                states_seen[i] += 1;
                assert_ne!(state.phase, ArmPhase::Stopped, "arm {} stopped", i + 1);
            }
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(
        states_seen.iter().all(|&n| n > 100),
        "the arms went quiet after the console died: {states_seen:?}"
    );

    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(stack.id() as i32),
        nix::sys::signal::Signal::SIGINT,
    )
    .expect("stop the stack");
    let (exit, _stdout, stderr) = wait_with_watchdog(stack, Duration::from_secs(60));
    assert!(exit.success(), "harvest up failed: {stderr}");
    assert!(stderr.contains("control token: "), "{stderr}");
    assert!(
        !harvest_operator::token::token_path(&domain).exists(),
        "the token file outlived the stack"
    );
    drop((
        mode_in,
        arms_in,
        commands_in,
        vacuum_in,
        estop_in,
        events_in,
        health_in,
        marks_in,
    ));
    drop(context);
    assert_eq!(leftover_files(&domain), "");
}
