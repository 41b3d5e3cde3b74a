//! The application's side of a stream session: [`Session::connect`], then frames in through a
//! [`FrameSender`] (paced by the [`Rate`]) and [`Event`]s out of [`Events`].

use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;

use tokio::sync::{mpsc, oneshot, watch};
use tokio::time::{Interval, MissedTickBehavior};

use super::clock::Stamp;
use super::config::{ClientConfig, Rate};
use super::connection::{Link, LinkState, Outgoing};
use super::event::{Event, Frame, ServerInfo};
use super::{proto, ClientError};

/// Frames handed over but not yet written to the socket.
const FRAME_QUEUE: usize = 2;

/// A connected stream session: send frames, receive events. Split it to send and receive from
/// different tasks; either way, keep reading events (when [`ClientConfig::event_capacity`]
/// of them are unread the connection stops reading the socket).
///
/// ```no_run
/// # async fn demo(png: Vec<u8>) -> Result<(), tre_client::ClientError> {
/// use tre_client::{ClientConfig, Event, Frame, Session};
/// let cfg = ClientConfig { server: "ws://10.0.0.2:8080/v1/stream".into(), ..ClientConfig::default() };
/// let mut session = Session::connect(cfg).await?;
/// let sequence = session.send(Frame::rgb(png)).await?;
/// while let Some(event) = session.next_event().await {
///     if let Event::Result(r) = &event {
///         println!("frame {}: {:?} round trip", r.sequence, r.latency);
///     }
///     if event.settles() == Some(sequence) {
///         break;
///     }
/// }
/// # Ok(())
/// # }
/// ```
#[derive(Debug)]
pub struct Session {
    sender: FrameSender,
    events: Events,
    server: ServerInfo,
}

impl Session {
    /// Checks `cfg`, connects (waiting for `/readyz` if asked), sends the Hello and waits for
    /// Ready, retrying with the back-off. Fails at once on a setting or a refusal that
    /// retrying will not fix.
    pub async fn connect(cfg: ClientConfig) -> Result<Self, ClientError> {
        let endpoints = cfg.validate()?;
        let (tx, frames) = mpsc::channel(FRAME_QUEUE);
        let (events_tx, events) = mpsc::channel(cfg.event_capacity);
        let (state_tx, state) = watch::channel(LinkState::default());
        let rate = cfg.rate;
        let link = Link::new(cfg, endpoints, frames, events_tx, state_tx)?;
        let (first_tx, first) = oneshot::channel();
        tokio::spawn(link.run(first_tx));
        let server = first.await.map_err(|_| ClientError::Closed)??;
        Ok(Self {
            sender: FrameSender::new(tx, state, rate),
            events: Events { rx: events },
            server,
        })
    }

    /// What the server said when it accepted the Hello.
    pub fn server(&self) -> &ServerInfo {
        &self.server
    }

    /// Sends a frame; see [`FrameSender::send`].
    pub async fn send(&mut self, frame: Frame) -> Result<u64, ClientError> {
        self.sender.send(frame).await
    }

    /// The next event; `None` once the session has ended.
    pub async fn next_event(&mut self) -> Option<Event> {
        self.events.recv().await
    }

    /// No more frames: the session ends once every frame sent has its answer. Read the rest
    /// of the events from the result.
    pub fn finish(self) -> Events {
        self.events
    }

    /// The sending and receiving halves, for use from different tasks. Dropping the sender
    /// ends the session once every frame sent has its answer.
    pub fn split(self) -> (FrameSender, Events) {
        (self.sender, self.events)
    }
}

/// The sending half of a session.
#[derive(Debug)]
pub struct FrameSender {
    tx: mpsc::Sender<Outgoing>,
    state: watch::Receiver<LinkState>,
    rate: Rate,
    ticker: Option<Interval>,
    next_sequence: u64,
    sent: u64,
}

impl FrameSender {
    fn new(tx: mpsc::Sender<Outgoing>, state: watch::Receiver<LinkState>, rate: Rate) -> Self {
        let ticker = match rate {
            Rate::Fixed(fps) => {
                let mut t = tokio::time::interval(Duration::from_secs_f64(1.0 / fps));
                // Ticks keep their phase, as a camera's frames do: a late frame does not push
                // the next ones back (that lowered the rate), and ticks missed by a slower
                // source are skipped, never sent in a burst.
                t.set_missed_tick_behavior(MissedTickBehavior::Skip);
                Some(t)
            }
            Rate::AsFastAsResults => None,
        };
        Self {
            tx,
            state,
            rate,
            ticker,
            next_sequence: 1,
            sent: 0,
        }
    }

    /// The sequence number the next frame will get (they count up from 1).
    pub fn next_sequence(&self) -> u64 {
        self.next_sequence
    }

    /// Waits for the frame's turn (the next tick of a fixed rate, or the previous frame's
    /// answer and a live connection), stamps it, and hands it to the connection. Returns its
    /// sequence number; its answer comes as an [`Event`] with the same number.
    pub async fn send(&mut self, frame: Frame) -> Result<u64, ClientError> {
        self.pace().await?;
        let sequence = self.next_sequence;
        let sent = Stamp::now();
        let bytes = proto::frame(frame, sequence, sent.unix_us);
        let limit = self.state.borrow().max_message_bytes;
        if limit > 0 && bytes.len() > limit {
            return Err(ClientError::FrameTooLarge {
                bytes: bytes.len(),
                limit,
            });
        }
        let out = Outgoing {
            sequence,
            bytes,
            sent,
        };
        self.tx.send(out).await.map_err(|_| ClientError::Closed)?;
        self.next_sequence += 1;
        self.sent += 1;
        Ok(sequence)
    }

    async fn pace(&mut self) -> Result<(), ClientError> {
        if let (Rate::Fixed(_), Some(t)) = (self.rate, self.ticker.as_mut()) {
            t.tick().await;
        }
        let (sent, rate) = (self.sent, self.rate);
        let ready = |s: &LinkState| match rate {
            Rate::Fixed(_) => true,
            Rate::AsFastAsResults => s.closed || (s.connected && s.settled >= sent),
        };
        let state = *self
            .state
            .wait_for(ready)
            .await
            .map_err(|_| ClientError::Closed)?;
        if state.closed {
            return Err(ClientError::Closed);
        }
        Ok(())
    }
}

/// The receiving half of a session; also a [`futures_util::Stream`] of [`Event`]s.
#[derive(Debug)]
pub struct Events {
    rx: mpsc::Receiver<Event>,
}

impl Events {
    /// The next event; `None` once the session has ended.
    pub async fn recv(&mut self) -> Option<Event> {
        self.rx.recv().await
    }
}

impl futures_util::Stream for Events {
    type Item = Event;

    fn poll_next(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Event>> {
        self.rx.poll_recv(cx)
    }
}
