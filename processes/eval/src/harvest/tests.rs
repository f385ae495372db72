use super::*;

#[test]
#[ignore]
fn scratch() {
    let _ = tracing_subscriber::fmt()
        .with_env_filter(std::env::var("RUST_LOG").unwrap_or_default())
        .try_init();
    let env = |k: &str, d: &str| std::env::var(k).unwrap_or(d.to_owned());
    for policy in [PolicyArg::Baseline, PolicyArg::V2023, PolicyArg::V2024].into_iter().filter(|p| env("POL", "all") == "all" || format!("{p:?}") == env("POL", "")) {
        let args = EvalHarvestArgs {
            policy,
            scenario: env("SCEN", "ideal"),
            arms: env("ARMS", "2").parse().unwrap(),
            episodes: env("EPS", "1").parse().unwrap(),
            detection_noise: env("NOISE", "1").parse().unwrap(),
            timing: if env("TIMING", "") == "fig12" {
                TimingArg::Fig12
            } else {
                TimingArg::Scenario
            },
            json: Some(format!("/tmp/harvest_{policy:?}.json").into()),
            ..EvalHarvestArgs::default()
        };
        let report = run_eval_harvest(&args).expect("run");
        println!("{}", report.render_text());
    }
}
