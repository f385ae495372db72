//! The lint levels that live in crate roots rather than in the workspace's `[lints]` table hold
//! for every crate: read from `cargo metadata`, each library, binary and example of the workspace
//! (test fixtures and the test-support crate aside) denies `unwrap`/`expect` outside tests, every
//! crate but the few that need `unsafe` forbids it, and the foundation and device crates deny
//! undocumented public items. A new crate that forgets one of them fails here, naming its root.

use serde_json::Value;

/// Denies `unwrap`/`expect` in the crate's own code but not in its unit tests; integration tests
/// are crates of their own without this line, so test code never needs a header to unwrap.
const DENY_UNWRAP: &str = "#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]";
const FORBID_UNSAFE: &str = "#![forbid(unsafe_code)]";
const DENY_MISSING_DOCS: &str = "#![deny(missing_docs)]";

/// Packages whose library needs `unsafe` (shared-memory payloads and signal handlers, the child
/// set-up between fork and exec, foreign transports of the benchmarks, the Aravis library
/// loaded at run time); every block is explained
/// by a `// SAFETY:` comment (`clippy::undocumented_unsafe_blocks` is denied workspace-wide).
const UNSAFE_LIBRARIES: [&str; 4] = [
    "harvest-ipc",
    "harvest-supervisor",
    "harvest-bench",
    "harvest-aravis",
];
/// Packages whose public items and fields are all documented.
const DOCUMENTED: [&str; 4] = [
    "harvest-ipc",
    "harvest-ipc-derive",
    "harvest-hw",
    "harvest-aravis",
];
/// Test code: may unwrap.
const TEST_SUPPORT: &str = "harvest-test-support";

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

/// The crate-level attributes of a root file (`#![...]` lines, possibly spread over lines).
fn has_attribute(root: &str, attribute: &str) -> bool {
    root.lines().any(|line| line.trim() == attribute)
}

#[test]
fn every_crate_root_carries_the_lint_levels() {
    let metadata = metadata();
    let tests_dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests");
    let mut missing = Vec::new();
    let mut roots_checked = 0;
    for package in metadata["packages"].as_array().expect("packages") {
        let package_name = package["name"].as_str().expect("package name");
        for target in package["targets"].as_array().expect("targets") {
            let kinds: Vec<&str> = target["kind"]
                .as_array()
                .expect("target kinds")
                .iter()
                .filter_map(Value::as_str)
                .collect();
            let is_lib = kinds
                .iter()
                .any(|kind| ["lib", "proc-macro", "rlib"].contains(kind));
            let is_bin_or_example = kinds.iter().any(|kind| ["bin", "example"].contains(kind));
            if !is_lib && !is_bin_or_example {
                continue; // tests and benches: test code
            }
            let path = std::path::PathBuf::from(target["src_path"].as_str().expect("src_path"));
            if path.starts_with(&tests_dir) {
                continue; // fault-injection fixtures of the tests
            }
            let root = std::fs::read_to_string(&path).expect("crate root readable");
            roots_checked += 1;
            let shown = path.display();
            if package_name != TEST_SUPPORT && !has_attribute(&root, DENY_UNWRAP) {
                missing.push(format!("{shown}: {DENY_UNWRAP}"));
            }
            let may_be_unsafe = is_lib && UNSAFE_LIBRARIES.contains(&package_name);
            if !may_be_unsafe && !has_attribute(&root, FORBID_UNSAFE) {
                missing.push(format!("{shown}: {FORBID_UNSAFE}"));
            }
            if is_lib
                && DOCUMENTED.contains(&package_name)
                && !has_attribute(&root, DENY_MISSING_DOCS)
            {
                missing.push(format!("{shown}: {DENY_MISSING_DOCS}"));
            }
        }
    }
    assert!(roots_checked > 30, "only {roots_checked} crate roots found");
    assert!(
        missing.is_empty(),
        "crate roots without their lint levels:\n{}",
        missing.join("\n")
    );
}
