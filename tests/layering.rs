//! The crate graph points one way (ARCHITECTURE.md, "Layers"): read from `cargo metadata`, every
//! workspace crate declares its layer (`[package.metadata.harvest] layer = ...`) and this test
//! fails, naming the offending edge, when
//! - an onboard crate (foundation, device, domain, runtime, process) has a non-dev dependency path to the
//!   simulator or a tool (layer `sim` or `tool`, or a package name with `sim`, `eval` or
//!   `bench`);
//! - a crate depends on a layer above its own, or a process crate on another process crate;
//! - a domain library depends on the transport's ports (`iceoryx2`) or a command line (`clap`);
//! - the CLI package links the simulator or a tool other than through an optional dependency
//!   (the `sim-tools` feature; `--no-default-features` builds the onboard binary).

use serde_json::Value;
use std::collections::BTreeMap;

/// Layers from the bottom up; a crate may depend on its own layer or those below (but see the
/// process and domain rules).
const ONBOARD_LAYERS: [&str; 5] = ["foundation", "device", "domain", "runtime", "process"];
const BESIDE_LAYERS: [&str; 2] = ["sim", "tool"];
const CLI_LAYER: &str = "cli";
/// Package-name markers of the simulator, evaluation and benchmark crates.
const OFF_ROBOT_NAME_MARKERS: [&str; 3] = ["sim", "eval", "bench"];
/// External crates a domain library must not use directly.
const NOT_IN_DOMAIN: [&str; 2] = ["iceoryx2", "clap"];

#[derive(Debug, Clone)]
struct Dependency {
    name: String,
    /// `None` for normal dependencies, `Some("dev")` / `Some("build")`.
    kind: Option<String>,
    optional: bool,
}

#[derive(Debug, Clone)]
struct Crate {
    layer: String,
    dependencies: Vec<Dependency>,
}

/// Workspace crates by package name, from `cargo metadata --no-deps` output.
fn workspace_crates(metadata: &Value) -> Result<BTreeMap<String, Crate>, String> {
    let mut crates = BTreeMap::new();
    for package in metadata["packages"].as_array().ok_or("no packages")? {
        let name = package["name"]
            .as_str()
            .ok_or("package without name")?
            .to_owned();
        let layer = package["metadata"]["harvest"]["layer"]
            .as_str()
            .ok_or_else(|| {
                format!("{name}: no [package.metadata.harvest] layer in its Cargo.toml")
            })?
            .to_owned();
        let dependencies = package["dependencies"]
            .as_array()
            .ok_or("dependencies")?
            .iter()
            .map(|dependency| Dependency {
                name: dependency["name"].as_str().unwrap_or_default().to_owned(),
                kind: dependency["kind"].as_str().map(str::to_owned),
                optional: dependency["optional"].as_bool().unwrap_or(false),
            })
            .collect();
        crates.insert(
            name,
            Crate {
                layer,
                dependencies,
            },
        );
    }
    Ok(crates)
}

fn is_off_robot(name: &str, krate: &Crate) -> bool {
    BESIDE_LAYERS.contains(&krate.layer.as_str())
        || OFF_ROBOT_NAME_MARKERS
            .iter()
            .any(|marker| name.split('-').any(|part| part == *marker))
}

fn rank(layer: &str) -> Option<usize> {
    ONBOARD_LAYERS.iter().position(|known| *known == layer)
}

/// Every violation of the rules in the module docs, each naming the edge (or path) that breaks
/// it.
fn layering_violations(crates: &BTreeMap<String, Crate>) -> Vec<String> {
    let mut violations = Vec::new();
    let known_layers: Vec<&str> = ONBOARD_LAYERS
        .iter()
        .chain(BESIDE_LAYERS.iter())
        .copied()
        .chain([CLI_LAYER])
        .collect();
    for (name, krate) in crates {
        if !known_layers.contains(&krate.layer.as_str()) {
            violations.push(format!("{name}: unknown layer {:?}", krate.layer));
        }
        if rank(&krate.layer).is_some() && is_off_robot(name, krate) {
            violations.push(format!(
                "{name}: layer {} but its name marks it as simulator/evaluation/benchmark",
                krate.layer
            ));
        }
    }
    for (name, krate) in crates {
        let normal = krate
            .dependencies
            .iter()
            .filter(|dependency| dependency.kind.as_deref() != Some("dev"));
        for dependency in normal {
            if krate.layer == "domain" && NOT_IN_DOMAIN.contains(&dependency.name.as_str()) {
                violations.push(format!(
                    "{name} -> {}: a domain library uses no transport ports and no command line",
                    dependency.name
                ));
            }
            let Some(target) = crates.get(&dependency.name) else {
                continue;
            };
            if krate.layer == CLI_LAYER {
                if is_off_robot(&dependency.name, target) && !dependency.optional {
                    violations.push(format!(
                        "{name} -> {}: the CLI links the simulator and tools only through the \
                         optional sim-tools feature",
                        dependency.name
                    ));
                }
                continue;
            }
            let (Some(from), Some(to)) = (rank(&krate.layer), rank(&target.layer)) else {
                continue;
            };
            if to > from {
                violations.push(format!(
                    "{name} ({}) -> {} ({}): depends on a higher layer",
                    krate.layer, dependency.name, target.layer
                ));
            }
            if krate.layer == "process" && target.layer == "process" {
                violations.push(format!(
                    "{name} -> {}: a process crate depends on another process crate",
                    dependency.name
                ));
            }
        }
    }
    // Onboard crates (and the CLI's mandatory part) reach no simulator or tool crate by any
    // non-dev path: report the path.
    for (name, krate) in crates {
        let onboard = rank(&krate.layer).is_some() || krate.layer == CLI_LAYER;
        if !onboard {
            continue;
        }
        let mut stack: Vec<Vec<String>> = vec![vec![name.clone()]];
        let mut seen = vec![name.clone()];
        while let Some(path) = stack.pop() {
            let Some(last) = path.last() else { continue };
            let Some(current) = crates.get(last) else {
                continue;
            };
            for dependency in &current.dependencies {
                let skipped = dependency.kind.as_deref() == Some("dev")
                    || (current.layer == CLI_LAYER && dependency.optional);
                if skipped || seen.contains(&dependency.name) {
                    continue;
                }
                let Some(target) = crates.get(&dependency.name) else {
                    continue;
                };
                let mut next = path.clone();
                next.push(dependency.name.clone());
                if is_off_robot(&dependency.name, target) {
                    violations.push(format!(
                        "onboard {name} reaches {} ({}): {}",
                        dependency.name,
                        target.layer,
                        next.join(" -> ")
                    ));
                    continue;
                }
                seen.push(dependency.name.clone());
                stack.push(next);
            }
        }
    }
    violations
}

fn metadata() -> Value {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    let output = std::process::Command::new(cargo)
        .args(["metadata", "--format-version", "1", "--no-deps"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo metadata runs");
    assert!(
        output.status.success(),
        "cargo metadata: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).expect("cargo metadata prints JSON")
}

#[test]
fn the_workspace_crate_graph_points_one_way() {
    let crates = workspace_crates(&metadata()).expect("every crate declares its layer");
    let violations = layering_violations(&crates);
    assert!(
        violations.is_empty(),
        "layering violations:\n{}",
        violations.join("\n")
    );
    // The layers hold what ARCHITECTURE.md says they hold.
    for (name, layer) in [
        ("harvest-ipc", "foundation"),
        ("harvest-hw", "device"),
        ("harvest-perception", "domain"),
        ("harvest-arm-process", "process"),
        ("harvest-sim", "sim"),
        ("harvest-eval", "tool"),
        ("harvest-bench", "tool"),
    ] {
        assert_eq!(crates[name].layer, layer, "{name}");
    }
}

/// The checker itself: an edge that breaks a rule is reported by name.
#[test]
fn an_added_edge_from_onboard_to_the_simulator_is_named() {
    let mut crates = workspace_crates(&metadata()).expect("layers");
    let added = |crates: &mut BTreeMap<String, Crate>, from: &str, to: &str| {
        crates
            .get_mut(from)
            .expect("crate")
            .dependencies
            .push(Dependency {
                name: to.to_owned(),
                kind: None,
                optional: false,
            });
    };
    // perception -> lidar -> sim: the path through the domain library is named.
    added(&mut crates, "harvest-lidar", "harvest-sim");
    let violations = layering_violations(&crates);
    assert!(
        violations
            .iter()
            .any(|violation| violation
                .contains("harvest-perception -> harvest-lidar -> harvest-sim")),
        "{violations:#?}"
    );

    let mut crates = workspace_crates(&metadata()).expect("layers");
    added(&mut crates, "harvest-vacuum-process", "harvest-arm-process");
    let violations = layering_violations(&crates);
    assert!(
        violations.iter().any(|violation| violation
            == "harvest-vacuum-process -> harvest-arm-process: a process crate depends on another process crate"),
        "{violations:#?}"
    );

    let mut crates = workspace_crates(&metadata()).expect("layers");
    added(&mut crates, "harvest-arm", "clap");
    added(&mut crates, "harvest", "harvest-eval");
    let violations = layering_violations(&crates);
    assert!(
        violations
            .iter()
            .any(|violation| violation.starts_with("harvest-arm -> clap")),
        "{violations:#?}"
    );
    assert!(
        violations
            .iter()
            .any(|violation| violation.starts_with("harvest -> harvest-eval")),
        "{violations:#?}"
    );
}
