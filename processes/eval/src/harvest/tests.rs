use super::*;

#[test]
#[ignore]
fn scratch() {
    let _ = tracing_subscriber::fmt()
        .with_env_filter(std::env::var("RUST_LOG").unwrap_or_default())
        .try_init();
    for policy in [PolicyArg::Baseline, PolicyArg::V2023, PolicyArg::V2024] {
        let args = EvalHarvestArgs {
            policy,
            timing: std::env::var("TIMING")
                .map(|t| {
                    if t == "fig12" {
                        TimingArg::Fig12
                    } else {
                        TimingArg::Scenario
                    }
                })
                .unwrap_or(TimingArg::Scenario),
            json: Some(format!("/tmp/harvest_{policy:?}.json").into()),
            ..EvalHarvestArgs::default()
        };
        let report = run_eval_harvest(&args).expect("run");
        println!("{}", report.render_text());
    }
}
