//! The stable error codes of the service, one list for both ends and both transports: the
//! `code` of HTTP error bodies (`{"error": {"code", "message"}}`) and of the stream's `Error`
//! messages, with the HTTP status of each.

/// Stable error codes, shared by HTTP bodies and stream `Error` messages.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Hash,
    serde::Serialize,
    serde::Deserialize,
    strum::IntoStaticStr,
    strum::EnumIter,
    strum::EnumString,
)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
#[strum(serialize_all = "snake_case")]
pub enum ErrorCode {
    /// Malformed request: query, multipart, missing part, not a WebSocket upgrade (400).
    BadRequest,
    /// No such route (404).
    NotFound,
    /// A route that exists, with another method (405).
    MethodNotAllowed,
    /// No API key, or not the server's (401): `--api-key`.
    Unauthorized,
    /// A browser origin not on `--allow-origin` (403).
    Forbidden,
    /// The request's headers or body did not arrive in time (408): `--header-timeout-ms`,
    /// `--body-timeout-ms`, `--min-body-rate`.
    RequestTimeout,
    /// Body or WebSocket message larger than the limit, or an image with too many pixels (413).
    TooLarge,
    /// Not a PNG or JPEG (415).
    UnsupportedMedia,
    /// A PNG or JPEG that cannot be decoded: truncated, corrupt, zero-size (422).
    BadImage,
    /// Depth of another size than the RGB frame, or not 16-bit grey / float .npy (422).
    BadDepth,
    /// Camera JSON that does not parse or whose values are nonsense (422).
    BadCamera,
    /// Inputs that do not fit the chosen mode (422).
    BadInput,
    /// Too many concurrent requests (429).
    TooManyRequests,
    /// The work queue is full (503).
    Overloaded,
    /// Models still loading or warming up, or shutting down (503).
    NotReady,
    /// The request took longer than the timeout (503).
    Timeout,
    /// A failure inside the service (500).
    Internal,
}

impl ErrorCode {
    /// The HTTP status of this code: the one mapping of codes to statuses.
    #[must_use]
    pub fn http_status(self) -> u16 {
        match self {
            Self::BadRequest => 400,
            Self::NotFound => 404,
            Self::MethodNotAllowed => 405,
            Self::Unauthorized => 401,
            Self::Forbidden => 403,
            Self::RequestTimeout => 408,
            Self::TooLarge => 413,
            Self::UnsupportedMedia => 415,
            Self::BadImage | Self::BadDepth | Self::BadCamera | Self::BadInput => 422,
            Self::TooManyRequests => 429,
            Self::Overloaded | Self::NotReady | Self::Timeout => 503,
            Self::Internal => 500,
        }
    }

    /// The code as it appears on the wire (`bad_image`, ...).
    #[must_use]
    pub fn as_str(self) -> &'static str {
        self.into()
    }

    /// Whether the client may retry later (answered with `Retry-After`).
    #[must_use]
    pub fn retryable(self) -> bool {
        matches!(
            self,
            Self::TooManyRequests | Self::Overloaded | Self::NotReady | Self::Timeout
        )
    }
}

impl std::fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use strum::IntoEnumIterator;

    #[test]
    fn every_code_reads_back_from_its_wire_name() {
        for code in ErrorCode::iter() {
            assert_eq!(code.as_str().parse::<ErrorCode>(), Ok(code));
            assert_eq!(code.to_string(), code.as_str());
        }
        assert!("no_such_code".parse::<ErrorCode>().is_err());
    }
}
