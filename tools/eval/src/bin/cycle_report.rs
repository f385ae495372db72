//! Prints the cycle-model numbers of the harvest-vacuum policies: Fig. 12 per-apple cycle times
//! of the three policies on the ideal scenario, and single-arm vs. dual-arm time per attempt with
//! the field failure rates (Tables 2-3).
//!
//! `cargo run -p harvest-eval --release --bin cycle_report`

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

use harvest_eval::cycle_model::{CycleEpisode, FailureRates, fig12, run_episode, single_vs_dual};
use harvest_vacuum::policy::{PolicyKind, new_policy};

const APPLES_PER_ARM: u32 = 40;
const ATTEMPTS: u32 = 20_000;
const SEED: u64 = 2024;

fn main() -> anyhow::Result<()> {
    println!("Fig. 12, ideal scenario ({APPLES_PER_ARM} apples per arm, all successful)");
    println!(
        "{:<10} {:>18} {:>18} {:>10}",
        "policy", "steady s/apple", "episode s/apple", "paper"
    );
    for row in fig12(APPLES_PER_ARM)? {
        println!(
            "{:<10} {:>18.3} {:>18.3} {:>10.2}",
            row.policy.to_string(),
            row.steady_state_s_per_apple,
            row.makespan_s_per_apple,
            row.paper_s_per_apple
        );
    }
    let rates = FailureRates::field_2024();
    println!();
    println!(
        "Single vs. dual arm, {ATTEMPTS} attempts, failure rates per attempt: no seal {:.3}, \
         detach loss {:.4}, holding loss {:.4} (total {:.3}); field: 8.29 vs 5.97 s, 28 % less",
        rates.no_seal,
        rates.detach_loss,
        rates.holding_loss,
        rates.total()
    );
    println!(
        "{:<8} {:<10} {:>16} {:>16} {:>10} {:>10}",
        "jitter", "policy", "single s/att", "dual s/att", "less %", "success"
    );
    for jitter in [0.0, 0.5] {
        let base = CycleEpisode {
            failures: rates,
            movement_jitter: jitter,
            seed: SEED,
            ..CycleEpisode::ideal(0)
        };
        for policy in PolicyKind::ALL {
            let c = single_vs_dual(policy, &base, ATTEMPTS)?;
            println!(
                "{:<8.1} {:<10} {:>16.3} {:>16.3} {:>10.1} {:>10.3}",
                jitter,
                policy.to_string(),
                c.single_s_per_attempt,
                c.dual_s_per_attempt,
                c.reduction_pct,
                c.dual_success_rate
            );
        }
    }
    // The field figure also carries uneven work: one arm often has more reachable apples.
    println!();
    println!("2024 dual arm with uneven loads (jitter 0.5): share of attempts on the busier arm");
    let single = single_vs_dual(
        PolicyKind::V2024,
        &CycleEpisode {
            failures: rates,
            movement_jitter: 0.5,
            seed: SEED,
            ..CycleEpisode::ideal(0)
        },
        ATTEMPTS,
    )?;
    for share_pct in [50u32, 60, 72, 80] {
        let busy = ATTEMPTS * share_pct / 100;
        let episode = CycleEpisode {
            failures: rates,
            movement_jitter: 0.5,
            seed: SEED,
            attempts_per_arm: [busy, ATTEMPTS - busy],
            ..CycleEpisode::ideal(0)
        };
        let r = run_episode(new_policy(PolicyKind::V2024).as_ref(), &episode)?;
        let dual = r.seconds_per_attempt().unwrap_or(f64::NAN);
        println!(
            "  {share_pct:>3} %: {dual:.3} s/attempt, {:.1} % less than one arm",
            100.0 * (1.0 - dual / single.single_s_per_attempt)
        );
    }
    Ok(())
}
