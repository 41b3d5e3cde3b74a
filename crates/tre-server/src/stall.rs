//! Connections whose client stops reading: every accepted connection's writes fail once one of
//! them has made no progress for `--stall-timeout-ms`, which ends the connection (an HTTP
//! answer or a stream alike: upgraded streams write through the same connection). Without it,
//! a client that stops reading, such as a hung process with its socket still open, held its
//! connection and the answer waiting in it until the server stopped, and the shutdown waited
//! for it the whole grace time. A slow client that keeps taking bytes is not affected.

use std::future::Future;
use std::io;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;

use tokio::time::Sleep;

use super::watched::{Watch, Watched, WriteOp};

/// An IO whose writes (and flushes and shutdowns) fail with [`io::ErrorKind::TimedOut`] once
/// one has been pending for the limit without any progress in between; reads pass through.
pub(crate) type StallGuard<T> = Watched<T, Stall>;

/// The watch of a [`StallGuard`]: the limit, and the deadline of a pending write.
#[derive(Debug)]
pub(crate) struct Stall {
    limit: Duration,
    /// Started when a write is first found pending; cleared by any progress.
    deadline: Option<Pin<Box<Sleep>>>,
}

impl Stall {
    /// Guards `io` with `limit`.
    pub(crate) fn guard<T>(io: T, limit: Duration) -> StallGuard<T> {
        Watched::new(
            io,
            Self {
                limit,
                deadline: None,
            },
        )
    }
}

impl Watch for Stall {
    /// Passes a write's progress through, or, while it is pending, fails it at the deadline.
    fn wrote<R>(
        &mut self,
        cx: &mut Context<'_>,
        _op: WriteOp,
        poll: Poll<io::Result<R>>,
    ) -> Poll<io::Result<R>> {
        if poll.is_ready() {
            self.deadline = None;
            return poll;
        }
        let limit = self.limit;
        let deadline = self
            .deadline
            .get_or_insert_with(|| Box::pin(tokio::time::sleep(limit)));
        match deadline.as_mut().poll(cx) {
            Poll::Ready(()) => Poll::Ready(Err(io::Error::new(
                io::ErrorKind::TimedOut,
                format!(
                    "the client took nothing for {} ms (--stall-timeout-ms)",
                    limit.as_millis()
                ),
            ))),
            Poll::Pending => Poll::Pending,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tokio::io::AsyncWriteExt;

    /// A duplex pipe whose far end never reads: the writer fills its buffer, then stalls.
    #[tokio::test(start_paused = true)]
    async fn a_write_without_progress_fails_at_the_limit_and_progress_resets_it() {
        let (near, mut far) = tokio::io::duplex(1024);
        let mut guarded = Stall::guard(near, Duration::from_secs(5));
        // Taken bit by bit (each read within the limit): no error, however long it all takes.
        let reader = tokio::spawn(async move {
            let mut buf = [0u8; 256];
            let mut total = 0;
            while total < 8192 {
                tokio::time::sleep(Duration::from_secs(4)).await;
                total += tokio::io::AsyncReadExt::read(&mut far, &mut buf)
                    .await
                    .unwrap();
            }
            far
        });
        guarded.write_all(&[7u8; 8192 + 1024]).await.unwrap();
        let _far = reader.await.unwrap();
        // The far end no longer reads: the next write fails after 5 s, not before.
        let start = tokio::time::Instant::now();
        let e = guarded.write_all(&[7u8; 4096]).await.unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::TimedOut);
        assert_eq!(start.elapsed(), Duration::from_secs(5));
        assert!(e.to_string().contains("--stall-timeout-ms"), "{e}");
    }
}
