//! Who the console lets in: a bounded number of connections per client address and in all,
//! and a share of push sessions for watchers. The controlling session's push connection is
//! admitted beyond the watchers' share (a page full of watchers never locks the operator
//! out), and once a push connection is open the console never closes it to make room.
//!
//! Every admission is a slot that gives itself back when dropped.

use std::collections::HashMap;
use std::net::IpAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use serde_json::{Value, json};

/// The console's bounds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Open TCP connections from one client address.
    pub connections_per_address: usize,
    /// Open TCP connections in all.
    pub connections_total: usize,
    /// Push sessions of watchers (every session but the controlling one).
    pub watchers_total: usize,
    /// Push sessions of watchers from one client address.
    pub watchers_per_address: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            connections_per_address: 32,
            connections_total: 512,
            watchers_total: 32,
            watchers_per_address: 8,
        }
    }
}

/// Why a connection or a push session was not admitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum Refusal {
    /// The client address has its share of connections open.
    #[error("too many connections from this address ({0} open)")]
    AddressFull(usize),
    /// The console has all the connections it takes.
    #[error("the console is full ({0} connections open)")]
    ConsoleFull(usize),
    /// The watchers' share of push sessions is taken.
    #[error("no room for another watcher ({0} watching); the e-stop and commands still go through")]
    WatchersFull(usize),
    /// The client address has its share of push sessions.
    #[error("too many watchers from this address ({0} watching)")]
    AddressWatchersFull(usize),
}

#[derive(Debug, Default)]
struct Counts {
    connections: HashMap<IpAddr, usize>,
    connections_total: usize,
    watchers: HashMap<IpAddr, usize>,
    watchers_total: usize,
    controllers: usize,
}

/// The counts and the bounds (module docs).
#[derive(Debug)]
pub struct Admission {
    limits: Limits,
    counts: Mutex<Counts>,
    refused_connections: AtomicU64,
    refused_watchers: AtomicU64,
    /// Views a slow page skipped (a newer one was ready before it took the last).
    pub views_skipped: AtomicU64,
}

fn decrement(map: &mut HashMap<IpAddr, usize>, address: IpAddr) {
    if let Some(count) = map.get_mut(&address) {
        *count = count.saturating_sub(1);
        if *count == 0 {
            map.remove(&address);
        }
    }
}

impl Admission {
    pub fn new(limits: Limits) -> Arc<Self> {
        Arc::new(Self {
            limits,
            counts: Mutex::new(Counts::default()),
            refused_connections: AtomicU64::new(0),
            refused_watchers: AtomicU64::new(0),
            views_skipped: AtomicU64::new(0),
        })
    }

    fn counts(&self) -> std::sync::MutexGuard<'_, Counts> {
        self.counts.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Admits one TCP connection from `address`.
    pub fn connect(self: &Arc<Self>, address: IpAddr) -> Result<ConnectionSlot, Refusal> {
        let mut counts = self.counts();
        let from_address = counts.connections.get(&address).copied().unwrap_or(0);
        let refusal = if from_address >= self.limits.connections_per_address {
            Some(Refusal::AddressFull(from_address))
        } else if counts.connections_total >= self.limits.connections_total {
            Some(Refusal::ConsoleFull(counts.connections_total))
        } else {
            None
        };
        if let Some(refusal) = refusal {
            self.refused_connections.fetch_add(1, Ordering::Relaxed);
            return Err(refusal);
        }
        *counts.connections.entry(address).or_insert(0) += 1;
        counts.connections_total += 1;
        Ok(ConnectionSlot {
            admission: self.clone(),
            address,
        })
    }

    /// Admits one push session from `address`; `controlling` (the session the executive says
    /// is in control) is admitted beyond the watchers' share.
    pub fn watch(
        self: &Arc<Self>,
        address: IpAddr,
        controlling: bool,
    ) -> Result<WatcherSlot, Refusal> {
        let mut counts = self.counts();
        if controlling {
            counts.controllers += 1;
            return Ok(WatcherSlot {
                admission: self.clone(),
                address: None,
            });
        }
        let from_address = counts.watchers.get(&address).copied().unwrap_or(0);
        let refusal = if from_address >= self.limits.watchers_per_address {
            Some(Refusal::AddressWatchersFull(from_address))
        } else if counts.watchers_total >= self.limits.watchers_total {
            Some(Refusal::WatchersFull(counts.watchers_total))
        } else {
            None
        };
        if let Some(refusal) = refusal {
            self.refused_watchers.fetch_add(1, Ordering::Relaxed);
            return Err(refusal);
        }
        *counts.watchers.entry(address).or_insert(0) += 1;
        counts.watchers_total += 1;
        Ok(WatcherSlot {
            admission: self.clone(),
            address: Some(address),
        })
    }

    /// Push sessions open (watchers and controlling pages).
    pub fn sessions(&self) -> usize {
        let counts = self.counts();
        counts.watchers_total + counts.controllers
    }

    /// Counts for the status panel and the benchmarks.
    pub fn status_json(&self) -> Value {
        let counts = self.counts();
        json!({
            "connections": counts.connections_total,
            "addresses": counts.connections.len(),
            "watchers": counts.watchers_total,
            "controllers": counts.controllers,
            "refused_connections": self.refused_connections.load(Ordering::Relaxed),
            "refused_watchers": self.refused_watchers.load(Ordering::Relaxed),
            "views_skipped": self.views_skipped.load(Ordering::Relaxed),
        })
    }
}

/// One admitted connection; dropping it gives the slot back.
#[derive(Debug)]
pub struct ConnectionSlot {
    admission: Arc<Admission>,
    address: IpAddr,
}

impl ConnectionSlot {
    /// The client's address.
    pub fn address(&self) -> IpAddr {
        self.address
    }
}

impl Drop for ConnectionSlot {
    fn drop(&mut self) {
        let mut counts = self.admission.counts();
        decrement(&mut counts.connections, self.address);
        counts.connections_total = counts.connections_total.saturating_sub(1);
    }
}

/// One admitted push session; dropping it gives the slot back.
#[derive(Debug)]
pub struct WatcherSlot {
    admission: Arc<Admission>,
    /// `None` for the controlling session (outside the watchers' share).
    address: Option<IpAddr>,
}

impl Drop for WatcherSlot {
    fn drop(&mut self) {
        let mut counts = self.admission.counts();
        match self.address {
            Some(address) => {
                decrement(&mut counts.watchers, address);
                counts.watchers_total = counts.watchers_total.saturating_sub(1);
            }
            None => counts.controllers = counts.controllers.saturating_sub(1),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: IpAddr = IpAddr::V4(std::net::Ipv4Addr::new(10, 0, 0, 1));
    const B: IpAddr = IpAddr::V4(std::net::Ipv4Addr::new(10, 0, 0, 2));

    #[test]
    fn connections_are_bounded_per_address_and_in_all_and_given_back() {
        let admission = Admission::new(Limits {
            connections_per_address: 2,
            connections_total: 3,
            ..Limits::default()
        });
        let a1 = admission.connect(A).expect("a1");
        let _a2 = admission.connect(A).expect("a2");
        assert_eq!(admission.connect(A).err(), Some(Refusal::AddressFull(2)));
        let _b1 = admission.connect(B).expect("b1");
        assert_eq!(admission.connect(B).err(), Some(Refusal::ConsoleFull(3)));
        drop(a1);
        let _b2 = admission.connect(B).expect("a slot given back");
        assert_eq!(admission.status_json()["refused_connections"], 2);
        assert_eq!(admission.status_json()["connections"], 3);
    }

    #[test]
    fn the_controlling_session_is_admitted_when_watchers_fill_their_share() {
        let admission = Admission::new(Limits {
            watchers_total: 2,
            watchers_per_address: 1,
            ..Limits::default()
        });
        let _w1 = admission.watch(A, false).expect("w1");
        assert_eq!(
            admission.watch(A, false).err(),
            Some(Refusal::AddressWatchersFull(1))
        );
        let w2 = admission.watch(B, false).expect("w2");
        let c = IpAddr::V4(std::net::Ipv4Addr::new(10, 0, 0, 3));
        assert_eq!(
            admission.watch(c, false).err(),
            Some(Refusal::WatchersFull(2))
        );
        let controller = admission.watch(A, true).expect("the controller");
        assert_eq!(admission.status_json()["controllers"], 1);
        drop(controller);
        drop(w2);
        let _w3 = admission
            .watch(c, false)
            .expect("a watcher slot given back");
        assert_eq!(admission.status_json()["watchers"], 2);
        assert_eq!(admission.status_json()["controllers"], 0);
    }
}
