"""The DSAC sampler of docs/design.md in PyTorch, batched over pixels, for training.

Same definition as serving (`crates/tre-core/src/geometry/dsac/SAMPLER.md`) and its numpy
mirror (`dsac.py`): candidates are the 7×7 window, ρ the softmax of the logits over valid
candidates, each of K hypotheses draws 3 distinct candidates by inverting the CDF of ρ
renormalised without those already drawn, with uniforms from SplitMix64 of (seed, pixel,
hypothesis, draw); planes through the triples are scored by the soft inlier count
Σ sigmoid(β(τ − dist)). Given the same ρ, this module draws the same
triples as `dsac.sample_triple` (tests/test_dsac_torch.py checks every draw).

Training (`dsac_loss`) takes the softmax-weighted expectation of the hypotheses' normal errors
(the DSAC expectation over hypothesis selection) and its score-function gradient with respect to
ρ through the log-probability of each drawn triple. Inference (`dsac_normals`) takes the best
hypothesis, refits least squares on its inliers and orients the normal towards the camera.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

from .geometry import unfold7

CANDIDATES = 49
CENTRE = 24
_M64 = (1 << 64) - 1


def _s64(v: int) -> int:
    """A u64 constant as the int64 with the same bits."""
    return v - (1 << 64) if v >= 1 << 63 else v


def _srl(x: Tensor, s: int) -> Tensor:
    """Logical right shift of int64 bits."""
    return (x >> s) & ((1 << (64 - s)) - 1)


def splitmix64(x: Tensor) -> Tensor:
    """SplitMix64 as a mixing function on int64 tensors holding u64 bits (wrapping arithmetic)."""
    z = x + _s64(0x9E3779B97F4A7C15)
    z = (z ^ _srl(z, 30)) * _s64(0xBF58476D1CE4E5B9)
    z = (z ^ _srl(z, 27)) * _s64(0x94D049BB133111EB)
    return z ^ _srl(z, 31)


def uniforms(seed: int, pixels: Tensor, hypotheses: int, draws: int = 3) -> Tensor:
    """float64 uniforms in [0, 1), shape (hypotheses, draws, *pixels.shape), bit-identical to
    serving's `hash::uniform(seed, pixel, hypothesis, draw)`."""
    base = splitmix64(torch.tensor(_s64(seed & _M64), dtype=torch.int64)) ^ pixels.to(torch.int64)
    mixed = splitmix64(base)
    keys = torch.tensor(
        [[(j << 8) | d for d in range(draws)] for j in range(hypotheses)], dtype=torch.int64
    ).view(hypotheses, draws, *([1] * pixels.dim()))
    h = splitmix64(mixed.unsqueeze(0).unsqueeze(0) ^ keys)
    return _srl(h, 11).to(torch.float64) * 2.0**-53


def sample_triples(rho: Tensor, u: Tensor) -> tuple[Tensor, Tensor]:
    """Draws K triples per pixel from ρ (float64, P×49) with uniforms `u` (K×3×P).

    Returns the candidate indices (K×3×P, int64) and whether each triple exists (K×P): the
    remaining mass stayed positive and an eligible candidate was left for every draw.
    """
    k_all = torch.arange(CANDIDATES).view(1, CANDIDATES)
    # Serving's prefix sums run left to right in float64; so does an explicit loop here.
    cols = [rho[:, 0]]
    for k in range(1, CANDIDATES):
        cols.append(cols[-1] + rho[:, k])
    prefix = torch.stack(cols, 1)
    n_hyp = u.shape[0]
    out = torch.zeros(n_hyp, 3, rho.shape[0], dtype=torch.int64)
    ok = torch.ones(n_hyp, rho.shape[0], dtype=torch.bool)
    positive = rho > 0.0
    for j in range(n_hyp):
        total = prefix[:, -1].clone()
        f = prefix.clone()
        drawn = torch.zeros_like(positive)
        for d in range(3):
            if d > 0:
                prev = out[j, d - 1]
                r_prev = rho.gather(1, prev.view(-1, 1)).squeeze(1)
                total = total - r_prev
                f = f - torch.where(k_all >= prev.view(-1, 1), r_prev.view(-1, 1), 0.0)
            t = u[j, d] * total
            eligible = positive & ~drawn
            hits = eligible & (t.view(-1, 1) < f)
            any_hit = hits.any(1)
            first = torch.argmax(hits.to(torch.int8), 1)
            last = CANDIDATES - 1 - torch.argmax(eligible.flip(1).to(torch.int8), 1)
            pick = torch.where(any_hit, first, last)
            ok[j] &= (total > 0.0) & eligible.any(1)
            out[j, d] = pick
            drawn = drawn | (k_all == pick.view(-1, 1))
    return out, ok


def sample_triples_fast(rho: Tensor, u: Tensor) -> tuple[Tensor, Tensor]:
    """`sample_triples` by binary search, all hypotheses at once: the same definition, but the
    CDF without the drawn candidates is found by shifting `t` past them rather than rebuilt, so a
    draw can differ from serving's where a rounding error sits at a CDF step (tests measure how
    rarely). Used for training and caching, where speed counts."""
    p, n_hyp = rho.shape[0], u.shape[0]
    prefix = torch.cumsum(rho, 1).contiguous()
    positive = rho > 0.0
    n_pos = positive.sum(1, keepdim=True)
    ut = u.permute(2, 0, 1)
    picks: list[Tensor] = []
    ok = torch.ones(p, n_hyp, dtype=torch.bool)
    mass = torch.zeros(p, n_hyp, dtype=rho.dtype)
    for d in range(3):
        total = prefix[:, -1:] - mass
        t = (ut[:, :, d] * total).contiguous()
        k = torch.searchsorted(prefix, t, right=True)
        if picks:
            drawn_sorted = torch.sort(torch.stack(picks, 2), 2).values
            shift = torch.zeros_like(t)
            for e in range(d):
                e_k = drawn_sorted[:, :, e]
                hit = k >= e_k
                shift = shift + torch.where(hit, rho.gather(1, e_k), 0.0)
                k = torch.where(
                    hit, torch.searchsorted(prefix, (t + shift).contiguous(), right=True), k
                )
        ok &= (total > 0.0) & (n_pos > d)
        over = torch.nonzero(k >= CANDIDATES)
        if over.shape[0]:
            rows, hyps = over[:, 0], over[:, 1]
            eligible = positive[rows].clone()
            for q in picks:
                eligible[torch.arange(rows.shape[0]), q[rows, hyps]] = False
            last = CANDIDATES - 1 - torch.argmax(eligible.flip(1).to(torch.int8), 1)
            k[rows, hyps] = last
        picks.append(k.clamp(max=CANDIDATES - 1))
        mass = mass + rho.gather(1, picks[-1])
    return torch.stack(picks, 1).permute(2, 1, 0).contiguous(), ok.t().contiguous()


@dataclass(frozen=True)
class DsacSettings:
    """Sampler and scorer settings (docs/design.md defaults)."""

    hypotheses: int = 12
    inlier_threshold_m: float = 0.01
    softness: float = 5.0
    selection_alpha: float = 1.0
    """Training only: hypotheses are weighted by softmax(α · score)."""


@dataclass
class Hypotheses:
    """K hypotheses for P pixels."""

    triples: Tensor
    """K×3×P candidate indices."""
    exists: Tensor
    """K×P: the triple was drawn and its plane is not degenerate."""
    normals: Tensor
    """K×P×3 unit normals (arbitrary sign)."""
    scores: Tensor
    """K×P soft inlier counts (−∞ where the hypothesis does not exist)."""
    log_prob: Tensor
    """K×P log-probability of drawing the triple in its order (differentiable in ρ)."""


def pixel_candidates(points_m: Tensor, valid: Tensor) -> tuple[Tensor, Tensor]:
    """N×3×H×W points and N×1×H×W validity → candidates P×49×3 and their validity P×49, pixels
    in (n, y, x) order."""
    cands = unfold7(points_m).permute(0, 3, 4, 2, 1).reshape(-1, CANDIDATES, 3)
    cvalid = unfold7(valid).permute(0, 3, 4, 2, 1).reshape(-1, CANDIDATES) > 0.5
    return cands, cvalid


def candidate_rho(logits: Tensor, cvalid: Tensor, pixels: Tensor | None = None) -> Tensor:
    """N×49×H×W logits → ρ (P×49): softmax over the valid candidates, 0 elsewhere; with
    `pixels` (flat indices into the P pixels), only those rows, in that order."""
    lg = logits.permute(0, 2, 3, 1).reshape(-1, CANDIDATES)
    if pixels is not None:
        lg, cvalid = lg[pixels], cvalid[pixels]
    lg = torch.where(cvalid, lg, torch.full_like(lg, -1e9))
    rho = torch.softmax(lg, 1) * cvalid
    return rho / torch.clamp(rho.sum(1, keepdim=True), min=1e-30)


def hypotheses(
    cands: Tensor,
    cvalid: Tensor,
    rho: Tensor,
    u: Tensor,
    cfg: DsacSettings,
    exact: bool = False,
) -> Hypotheses:
    """Samples (no gradient), builds and scores the K hypotheses of every pixel; `log_prob`
    keeps the gradient to ρ. `exact` picks the draw-for-draw serving sampler over the fast one."""
    with torch.no_grad():
        sampler = sample_triples if exact else sample_triples_fast
        triples, drawn = sampler(rho.detach().to(torch.float64), u)
    cd = cands.to(torch.float64) if exact else cands
    pts = [cd[torch.arange(cd.shape[0]).unsqueeze(0), triples[:, d]] for d in range(3)]
    ab, ac = pts[1] - pts[0], pts[2] - pts[0]
    n = torch.linalg.cross(ab, ac)
    length = torch.linalg.vector_norm(n, dim=-1)
    scale = torch.linalg.vector_norm(ab, dim=-1) * torch.linalg.vector_norm(ac, dim=-1)
    exists = drawn & (length > 1e-9 * scale) & torch.isfinite(length)
    normals = n / torch.clamp(length, min=1e-30).unsqueeze(-1)
    tau = cfg.inlier_threshold_m
    beta = cfg.softness / tau
    # n·(q − a) = n·q − n·a, as one batched matrix product per pixel (P×K×3 @ P×3×49).
    nq = torch.bmm(normals.permute(1, 0, 2), cd.transpose(1, 2)).permute(1, 0, 2)
    dist = (nq - (normals * pts[0]).sum(-1, keepdim=True)).abs()
    soft = torch.sigmoid(beta * (tau - dist)) * cvalid.unsqueeze(0)
    scores = torch.where(exists, soft.sum(-1), torch.full_like(length, -torch.inf))
    log_prob = _log_prob(rho, triples)
    return Hypotheses(triples, exists, normals.to(cands.dtype), scores, log_prob)


def _log_prob(rho: Tensor, triples: Tensor) -> Tensor:
    """log P of each ordered triple under sampling without replacement from ρ."""
    k, _, p = triples.shape
    r = rho.unsqueeze(0).expand(k, p, CANDIDATES)
    picked = [r.gather(2, triples[:, d].unsqueeze(-1)).squeeze(-1) for d in range(3)]
    eps = 1e-12
    lp = torch.log(picked[0] + eps)
    lp = lp + torch.log(picked[1] + eps) - torch.log(torch.clamp(1 - picked[0], min=eps))
    rest = torch.clamp(1 - picked[0] - picked[1], min=eps)
    return lp + torch.log(picked[2] + eps) - torch.log(rest)


def dsac_loss(
    logits: Tensor,
    points_m: Tensor,
    valid: Tensor,
    normals_gt: Tensor,
    seed: int,
    cfg: DsacSettings = DsacSettings(),
    max_pixels: int | None = None,
) -> tuple[Tensor, Tensor]:
    """DSAC training loss for N×49×H×W logits; returns (loss to minimise, expected normal error
    in degrees for logging). Pixels without a valid point or ground-truth normal are skipped;
    with `max_pixels`, a random subset of that many (chosen from `seed`) is scored."""
    cands, cvalid = pixel_candidates(points_m, valid)
    gt = normals_gt.permute(0, 2, 3, 1).reshape(-1, 3)
    keep = cvalid[:, CENTRE] & torch.isfinite(gt).all(1)
    idx = torch.nonzero(keep).squeeze(1)
    if max_pixels is not None and idx.shape[0] > max_pixels:
        g = torch.Generator().manual_seed(seed)
        idx = idx[torch.randperm(idx.shape[0], generator=g)[:max_pixels]].sort().values
    rho = candidate_rho(logits, cvalid, idx)
    h, w = points_m.shape[2:]
    u = uniforms(seed, idx % (h * w), cfg.hypotheses)
    hyp = hypotheses(cands[idx], cvalid[idx], rho, u, cfg)
    cos = (hyp.normals * gt[idx].unsqueeze(0)).sum(-1).abs().clamp(max=1.0)
    err = torch.where(hyp.exists, 1.0 - cos, torch.ones_like(cos))
    w = torch.softmax(cfg.selection_alpha * torch.where(hyp.exists, hyp.scores, -1e4), 0)
    expected = (w * err).sum(0)
    advantage = (err - err.mean(0, keepdim=True)).detach()
    loss = (advantage * hyp.log_prob * hyp.exists).sum(0).mean()
    angle = torch.rad2deg(torch.acos((1.0 - expected).clamp(-1.0, 1.0))).mean()
    return loss, angle.detach()


def dsac_normals(
    logits: Tensor,
    points_m: Tensor,
    valid: Tensor,
    seed: int,
    cfg: DsacSettings = DsacSettings(),
    exact: bool = False,
    chunk: int = 16384,
) -> Tensor:
    """Serving's DSAC normals (best hypothesis, LS refit on its inliers, oriented towards the
    camera) for N×49×H×W logits: N×3×H×W, 0 where a pixel gets no normal. `exact` uses the
    draw-for-draw sampler and float64 scores; pixels go `chunk` at a time to bound memory."""
    n, _, h, w = points_m.shape
    with torch.no_grad():
        cands, cvalid = pixel_candidates(points_m, valid)
        keep = torch.nonzero(cvalid[:, CENTRE]).squeeze(1)
        out = torch.zeros(cands.shape[0], 3, dtype=torch.float64)
        for lo in range(0, keep.shape[0], chunk):
            idx = keep[lo : lo + chunk]
            u = uniforms(seed, idx % (h * w), cfg.hypotheses)
            rho = candidate_rho(logits, cvalid, idx)
            out[idx] = _best_refit(cands[idx], cvalid[idx], rho, u, cfg, exact)
    return out.view(n, h, w, 3).permute(0, 3, 1, 2).to(points_m.dtype)


def _best_refit(
    c: Tensor, cv: Tensor, rho: Tensor, u: Tensor, cfg: DsacSettings, exact: bool
) -> Tensor:
    """Steps 3–5 for P pixels: the best hypothesis refit on its inliers, oriented; 0 if none."""
    hyp = hypotheses(c, cv, rho, u, cfg, exact)
    best = torch.argmax(hyp.scores, 0)
    has = hyp.exists.any(0)
    pick = torch.arange(best.shape[0])
    c = c.to(torch.float64)
    nb = hyp.normals[best, pick].to(torch.float64)
    a = c[pick, hyp.triples[best, 0, pick]]
    dist = ((c - a.unsqueeze(1)) * nb.unsqueeze(1)).sum(-1).abs()
    inl = (cv & (dist < cfg.inlier_threshold_m)).to(torch.float64)
    refit = _ls_normals(c - c[:, CENTRE : CENTRE + 1], inl)
    normal = torch.where(torch.isfinite(refit).all(1, keepdim=True), refit, nb)
    p = c[:, CENTRE]
    normal = torch.where((normal * p).sum(1, keepdim=True) > 0, -normal, normal)
    return torch.where(has.unsqueeze(1), normal, torch.zeros_like(normal))


def _ls_normals(offsets: Tensor, weights: Tensor) -> Tensor:
    """Smallest-eigenvalue eigenvectors of the weighted covariances (P×49×3 offsets, P×49 0/1
    weights); NaN where fewer than 3 points or the eigenvalue gap is below 1e-6 of the scale.
    Closed form: eigenvalues from the trigonometric solution of the characteristic cubic, the
    eigenvector as the longest cross product of two rows of `C − λ_min·I`."""
    cnt = weights.sum(1, keepdim=True)
    mean = (offsets * weights.unsqueeze(-1)).sum(1) / torch.clamp(cnt, min=1)
    d = (offsets - mean.unsqueeze(1)) * weights.unsqueeze(-1)
    cov = d.transpose(1, 2) @ d / torch.clamp(cnt, min=1).unsqueeze(-1)
    scale = cov.abs().amax((1, 2), keepdim=True)
    a = cov / torch.clamp(scale, min=1e-300)
    q = (a[:, 0, 0] + a[:, 1, 1] + a[:, 2, 2]) / 3.0
    b = a - q.view(-1, 1, 1) * torch.eye(3, dtype=a.dtype)
    p2 = (b * b).sum((1, 2)) / 6.0
    pp = torch.sqrt(torch.clamp(p2, min=1e-300))
    det = torch.linalg.det(b / pp.view(-1, 1, 1))
    phi = torch.acos(torch.clamp(det / 2.0, -1.0, 1.0)) / 3.0
    lam_max = q + 2 * pp * torch.cos(phi)
    lam_min = q + 2 * pp * torch.cos(phi + 2.0 * torch.pi / 3.0)
    lam_mid = 3 * q - lam_max - lam_min
    m = a - lam_min.view(-1, 1, 1) * torch.eye(3, dtype=a.dtype)
    crosses = torch.stack(
        [
            torch.linalg.cross(m[:, 0], m[:, 1]),
            torch.linalg.cross(m[:, 0], m[:, 2]),
            torch.linalg.cross(m[:, 1], m[:, 2]),
        ],
        1,
    )
    lengths = torch.linalg.vector_norm(crosses, dim=-1)
    best = torch.argmax(lengths, 1)
    pick = torch.arange(a.shape[0])
    v = crosses[pick, best] / torch.clamp(lengths[pick, best], min=1e-300).unsqueeze(1)
    bad = (cnt.squeeze(1) < 3) | ~(lam_mid - lam_min > 1e-6) | ~(scale.view(-1) > 0)
    return torch.where(bad.unsqueeze(1), torch.full_like(v, torch.nan), v)
