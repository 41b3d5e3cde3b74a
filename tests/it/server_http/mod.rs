//! `POST /v1/roughness` and the operational endpoints on a real `tre serve` over loopback:
//! answers equal `tre infer`, every kind of bad input is a clear JSON error after which the
//! server still serves, and overload is refused at once while accepted work finishes.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use crate::common;

use std::io::Write;
use std::net::TcpStream;

use common::{get, infer_png16, png16_values, png_with_header, real, rt, Server};
use reqwest::multipart::{Form, Part};

mod answers;
mod assumptions;
mod auth;
mod bad_input;
mod overload;
mod slow_clients;

async fn post(url: &str, content_type: &str, body: Vec<u8>) -> reqwest::Response {
    reqwest::Client::new()
        .post(url)
        .header("content-type", content_type)
        .body(body)
        .send()
        .await
        .unwrap()
}

/// Posts `form` to `url` as multipart form data.
async fn post_form(url: &str, form: Form) -> reqwest::Response {
    reqwest::Client::new()
        .post(url)
        .multipart(form)
        .send()
        .await
        .unwrap()
}

/// Status, error code and message of a JSON error answer.
async fn error_of(resp: reqwest::Response) -> (u16, String, String) {
    let status = resp.status().as_u16();
    assert_eq!(resp.headers()["content-type"], "application/json");
    let v: serde_json::Value = serde_json::from_slice(&resp.bytes().await.unwrap()).unwrap();
    let e = &v["error"];
    (
        status,
        e["code"].as_str().unwrap().to_owned(),
        e["message"].as_str().unwrap().to_owned(),
    )
}

/// A small real frame must still be answered with a map (the server is still serving).
async fn still_serves(server: &Server) {
    let frame = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    let resp = post(
        &format!("{}/v1/roughness?mode=rgb", server.url()),
        "image/png",
        frame,
    )
    .await;
    assert_eq!(resp.status().as_u16(), 200, "the server stopped serving");
}
