//! The page sessions this station relayed, by the session id the executive knows them under.
//! The robot's link forwards a station's session under an id of its own
//! (`harvest_remote::remote_request::forwarded_session`), so the mode names that id as the
//! controller; a page recognises its own session only once it is translated back.

use std::collections::VecDeque;
use std::sync::Mutex;

use harvest_remote::remote_request::forwarded_session;

/// Sessions remembered (pages of one station; the oldest is forgotten first).
const REMEMBERED: usize = 256;

/// Forwarded id -> page session, for the sessions relayed lately.
#[derive(Debug, Default)]
pub struct RelayedSessions {
    sessions: Mutex<VecDeque<(u64, u64)>>,
}

impl RelayedSessions {
    /// A command of page session `session` goes over the link.
    pub fn note(&self, session: u64) {
        let forwarded = forwarded_session(session);
        let mut sessions = self.sessions.lock().unwrap_or_else(|p| p.into_inner());
        if sessions.iter().any(|&(f, _)| f == forwarded) {
            return;
        }
        if sessions.len() == REMEMBERED {
            sessions.pop_front();
        }
        sessions.push_back((forwarded, session));
    }

    /// The page session the executive's `session` is, if this station relayed it; else
    /// `session` itself (another station's, a console's on the robot, or none).
    pub fn page_session(&self, session: u64) -> u64 {
        self.sessions
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .iter()
            .find(|&&(forwarded, _)| forwarded == session)
            .map_or(session, |&(_, page)| page)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_relayed_session_is_recognised_and_others_pass_unchanged() {
        let relayed = RelayedSessions::default();
        relayed.note(17);
        relayed.note(17);
        assert_eq!(relayed.page_session(forwarded_session(17)), 17);
        assert_eq!(
            relayed.page_session(forwarded_session(18)),
            forwarded_session(18)
        );
        assert_eq!(relayed.page_session(0), 0);
        for session in 100..100 + REMEMBERED as u64 {
            relayed.note(session);
        }
        assert_eq!(
            relayed.page_session(forwarded_session(17)),
            forwarded_session(17)
        );
    }
}
