//! The application's side of OpenXR's session life cycle (OpenXR 1.0, section 9.3): what to do
//! on each `XrSessionState` the runtime reports, kept apart from the OpenXR calls so every
//! transition is tested without a runtime.

use openxr::SessionState;

/// Where the application stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// No session yet, or one that is idle (created, not begun).
    Idle,
    /// The runtime said READY; `xrBeginSession` is due.
    Ready,
    /// Begun: the frame loop runs (frames are submitted from SYNCHRONIZED on).
    Running,
    /// The runtime said STOPPING: `xrEndSession` is due; no more frames.
    Stopping,
    /// The runtime is losing the session (headset unplugged, runtime quit): destroy it and try
    /// to create a new one when the system is back. The session record is kept.
    LossPending,
    /// The session ends for good: destroy it and leave the frame loop.
    Exiting,
}

/// What the runtime's new state asks the application to do now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    BeginSession,
    EndSession,
    /// Destroy the session (and the swapchains and spaces made from it), then poll
    /// `xrGetSystem` until the runtime offers the headset again and create a new session.
    Recreate,
    /// Destroy the session and stop.
    Exit,
}

/// A state change the runtime is not allowed to make (OpenXR's state graph), kept so a test
/// runtime's mistakes show up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Unexpected {
    pub from: SessionState,
    pub to: SessionState,
}

/// Follows the runtime's session states.
#[derive(Debug, Clone)]
pub struct SessionMachine {
    phase: Phase,
    state: SessionState,
    /// Sessions lost and recreated.
    pub restarts: u32,
    /// Transitions OpenXR's graph does not allow.
    pub unexpected: Vec<Unexpected>,
    /// Every state in the order reported (the session log).
    pub history: Vec<SessionState>,
}

impl Default for SessionMachine {
    fn default() -> Self {
        Self::new()
    }
}

/// Whether OpenXR's state graph has an edge from `a` to `b` (LOSS_PENDING may come from any
/// state, and a new session starts at IDLE).
fn allowed(a: SessionState, b: SessionState) -> bool {
    use SessionState as S;
    if b == S::LOSS_PENDING {
        return true;
    }
    matches!(
        (a, b),
        (S::UNKNOWN, S::IDLE)
            | (S::IDLE, S::READY)
            | (S::IDLE, S::EXITING)
            | (S::READY, S::SYNCHRONIZED)
            | (S::SYNCHRONIZED, S::VISIBLE)
            | (S::SYNCHRONIZED, S::STOPPING)
            | (S::VISIBLE, S::FOCUSED)
            | (S::VISIBLE, S::SYNCHRONIZED)
            | (S::FOCUSED, S::VISIBLE)
            | (S::STOPPING, S::IDLE)
            | (S::LOSS_PENDING, S::IDLE)
    )
}

impl SessionMachine {
    pub fn new() -> Self {
        SessionMachine {
            phase: Phase::Idle,
            state: SessionState::UNKNOWN,
            restarts: 0,
            unexpected: Vec::new(),
            history: Vec::new(),
        }
    }

    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// The runtime's latest state.
    pub fn state(&self) -> SessionState {
        self.state
    }

    /// Frames go to the runtime (wait, begin, end) while the session is begun and not stopping.
    pub fn submits_frames(&self) -> bool {
        self.phase == Phase::Running
    }

    /// The images are shown to the trainee (VISIBLE or FOCUSED).
    pub fn visible(&self) -> bool {
        matches!(self.state, SessionState::VISIBLE | SessionState::FOCUSED)
    }

    /// Controller input and haptics reach this application only while FOCUSED.
    pub fn focused(&self) -> bool {
        self.state == SessionState::FOCUSED
    }

    /// The frame loop should go on (not exiting).
    pub fn alive(&self) -> bool {
        self.phase != Phase::Exiting
    }

    /// Takes the runtime's new state; returns what to do now.
    pub fn on_state(&mut self, to: SessionState) -> Option<Command> {
        let from = self.state;
        if !allowed(from, to) {
            self.unexpected.push(Unexpected { from, to });
        }
        self.history.push(to);
        self.state = to;
        use SessionState as S;
        match to {
            S::READY => {
                self.phase = Phase::Running;
                Some(Command::BeginSession)
            }
            S::SYNCHRONIZED | S::VISIBLE | S::FOCUSED => {
                // Reached only after READY began the session.
                None
            }
            S::STOPPING => {
                self.phase = Phase::Stopping;
                Some(Command::EndSession)
            }
            S::IDLE => {
                if self.phase != Phase::LossPending {
                    self.phase = Phase::Idle;
                }
                None
            }
            S::LOSS_PENDING => {
                self.phase = Phase::LossPending;
                Some(Command::Recreate)
            }
            S::EXITING => {
                self.phase = Phase::Exiting;
                Some(Command::Exit)
            }
            _ => None,
        }
    }

    /// A new session was created after a loss: its states start again from IDLE.
    pub fn recreated(&mut self) {
        self.restarts += 1;
        self.phase = Phase::Idle;
        self.state = SessionState::UNKNOWN;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use SessionState as S;

    #[test]
    fn a_normal_session_walks_ready_to_exiting_with_begin_and_end() {
        let mut m = SessionMachine::new();
        let mut cmds = Vec::new();
        for s in [
            S::IDLE,
            S::READY,
            S::SYNCHRONIZED,
            S::VISIBLE,
            S::FOCUSED,
            S::VISIBLE,
            S::SYNCHRONIZED,
            S::STOPPING,
            S::IDLE,
            S::EXITING,
        ] {
            if let Some(c) = m.on_state(s) {
                cmds.push(c);
            }
            match s {
                S::FOCUSED => assert!(m.focused() && m.visible() && m.submits_frames()),
                S::SYNCHRONIZED => assert!(!m.visible() && m.submits_frames()),
                S::STOPPING => assert!(!m.submits_frames()),
                _ => {}
            }
        }
        assert_eq!(
            cmds,
            [Command::BeginSession, Command::EndSession, Command::Exit]
        );
        assert!(!m.alive());
        assert!(m.unexpected.is_empty());
        assert_eq!(m.history.len(), 10);
    }

    #[test]
    fn a_lost_session_is_recreated_and_runs_again() {
        let mut m = SessionMachine::new();
        for s in [S::IDLE, S::READY, S::SYNCHRONIZED, S::VISIBLE, S::FOCUSED] {
            m.on_state(s);
        }
        assert_eq!(m.on_state(S::LOSS_PENDING), Some(Command::Recreate));
        assert_eq!(m.phase(), Phase::LossPending);
        assert!(!m.submits_frames() && m.alive());
        m.recreated();
        assert_eq!(m.restarts, 1);
        assert_eq!(m.on_state(S::IDLE), None);
        assert_eq!(m.on_state(S::READY), Some(Command::BeginSession));
        assert!(m.submits_frames());
        assert!(m.unexpected.is_empty(), "{:?}", m.unexpected);
    }

    #[test]
    fn a_transition_outside_openxrs_graph_is_noted() {
        let mut m = SessionMachine::new();
        m.on_state(S::IDLE);
        // FOCUSED straight from IDLE skips READY, SYNCHRONIZED and VISIBLE.
        m.on_state(S::FOCUSED);
        assert_eq!(
            m.unexpected,
            [Unexpected {
                from: S::IDLE,
                to: S::FOCUSED
            }]
        );
        // Exiting from a running session without stopping first is not allowed either.
        let mut n = SessionMachine::new();
        for s in [S::IDLE, S::READY, S::SYNCHRONIZED, S::EXITING] {
            n.on_state(s);
        }
        assert_eq!(n.unexpected.len(), 1);
        assert!(!n.alive());
    }
}
