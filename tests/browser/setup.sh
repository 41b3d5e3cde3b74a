#!/usr/bin/env bash
# Installs what tests/it/demo_page.rs needs on a fresh Debian machine: Debian's Chromium (only if
# it is missing) and playwright-core from package-lock.json. Playwright drives that Chromium;
# it downloads no browser of its own.
set -euo pipefail
cd "$(dirname "$0")"

chromium="${CHROMIUM:-/usr/bin/chromium}"
if [ ! -x "$chromium" ]; then
    echo "== installing Debian's chromium (no $chromium)"
    sudo=""
    if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
    $sudo apt-get update -qq
    $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium
fi

if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
    echo "tests/browser/setup.sh: node and npm are needed (Node.js >= 20)" >&2
    exit 1
fi
echo "== npm ci in tests/browser (playwright-core)"
npm ci --no-audit --no-fund
