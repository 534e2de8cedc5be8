"""The training stages as loss modules. Each freezes every stage before it (paper, sec. 3).

    vae    motion VAE: reconstruction + KL
    prior  latent denoiser (x0 prediction): latent loss + reconstruction through the frozen decoder
    hhi    Meta-Interaction Module for partners (prior frozen), same objectives, partner context
    hsi    Meta-Interaction Module for scenes and goals, same objectives, occupancy + goal context
    fwsr   frame-wise latent refinement (everything else frozen): the refined decode of frame f must
           match the real frame f given the latest real history and partner frames
    decoder the VAE's decoder alone (the encoder, so the latent space every stage above learned, frozen):
           reconstruction + the error of the motion as shown (the kinematics of the decoded rotations and
           pelvis), the segment's first frames most, so that a segment starts where its history ends
"""
from __future__ import annotations

from typing import Callable

import torch
from torch import nn

from ..errors import DEFAULT_GUIDANCE, RemogenError
from ..model import Contexts, ReMoGenModel, noise
from ..features import features_to_pose
from ..skeleton import forward_kinematics
from ..control import FPS, ControlConfig, foot_cost, glide_cost, seam_cost
from ..joints import JOINT_INDEX
from .recipe import (DECODER_FIRST_FRAMES, DECODER_SHOWN_WEIGHT, FWSR_OWN_SHARE, ROLLOUT_GLIDE_WEIGHT, ROLLOUT_MARGIN,
                     ROLLOUT_REACHING_JOINTS, ROLLOUT_ROWS, ROLLOUT_SEAM_WEIGHT, ROLLOUT_SKATE_WEIGHT, TEXT_DROP,
                     TEXT_JITTER_SHARE, WINDOW_RECIPES)
from .samples import Batch
from .text_jitter import jitter_text

STAGES = ("vae", "prior", "hhi", "hsi", "fwsr", "decoder")
# A refinement of a trained model: a file without it is complete (files made before it existed have none).
OPTIONAL_STAGES = ("decoder",)
REQUIRED_STAGES = tuple(s for s in STAGES if s not in OPTIONAL_STAGES)
TEXT_STAGES = ("prior", "hhi", "hsi")   # the stages that train the denoiser's text input (with caption dropout)
KL_WEIGHT = 1e-4
# The stages an anchored fine-tune (WindowRecipe.anchor) can hold to their start; the HHI stage holds the segments its
# rollout loss samples (WindowRecipe.hhi_rollout) to those the starting module samples from the same noise.
ANCHOR_STAGES = ("prior", "decoder", "hhi")


def own_recent_frames(model: ReMoGenModel, b: Batch, z0: torch.Tensor, gen: torch.Generator) -> torch.Tensor:
    """The ego's latest H frames before frame f as FWSR training sees them: real ones, or for FWSR_OWN_SHARE of
    the rows the generator's own decode of the segment (after the real history), which is what the refiner reads
    at run time, where the ego's recent frames are its own output. Trained on real recent frames only, the refiner
    learned to continue them, and at run time it amplified its own drift (measured on the val split)."""
    own = (torch.rand(z0.shape[0], generator=gen) < FWSR_OWN_SHARE).to(z0.device)
    if not bool(own.any()):
        return b.recent
    seq = torch.cat((b.hist, model.vae.decode(b.hist, z0)), 1)        # (B, H + F, D): history, then the segment
    frames = b.frame.unsqueeze(1) + torch.arange(b.hist.shape[1], device=z0.device)   # frames f .. f+H-1 of seq
    mine = seq[torch.arange(z0.shape[0], device=z0.device).unsqueeze(1), frames]
    return torch.where(own.view(-1, 1, 1), mine, b.recent)


def shown_joints(stats, feats_n: torch.Tensor) -> torch.Tensor:
    """(..., T, 22, 3) the joints of normalised features (..., T, D) as the runtime shows them: forward kinematics
    of their rotations and pelvis."""
    return forward_kinematics(*features_to_pose(stats.denormalize(feats_n)))[0]


def shown_joint_error(stats, decoded_n: torch.Tensor, real_n: torch.Tensor) -> torch.Tensor:
    """(F,) mean joint distance (m) per segment frame between the motion shown for decoded and for real
    normalised features (B, F, D): forward kinematics of their rotations and pelvis, as the runtime shows it."""
    shown = shown_joints(stats, decoded_n)
    with torch.no_grad():
        real = shown_joints(stats, real_n)
    return (shown - real).norm(dim=-1).mean((0, 2))


def clearance_charge(ego: torch.Tensor, partner: torch.Tensor, present: torch.Tensor,
                     ego_joints: list[int] | None = None) -> torch.Tensor:
    """Mean over the frames where the partner is there of relu(ROLLOUT_MARGIN - clearance)^2, clearance being the
    distance between the nearest joints of the two bodies (of the ego, only `ego_joints` when given). ego (R, F, 22,
    3); partner (R, F + L, 22, 3) and present (R, F + L): its last L frames are checked against the ego's last pose
    (a segment must end out of the way of where the partner goes next, as test-time control asks)."""
    if ego_joints is not None:
        ego = ego[:, :, ego_joints]
    last = ego[:, -1:].expand(-1, partner.shape[1] - ego.shape[1], -1, -1)
    held = torch.cat((ego, last), 1)
    gap = torch.cdist(held.flatten(0, 1), partner.flatten(0, 1)).amin((1, 2)).view(present.shape)
    return (torch.relu(ROLLOUT_MARGIN - gap).pow(2) * present).sum() / present.sum().clamp_min(1)


def rollout_joints(model: ReMoGenModel, b: Batch, rows: slice, gen: torch.Generator) -> torch.Tensor:
    """(R, F, 22, 3) the ego's joints over the segment `model` samples for the rows' windows, in their canonical
    frame, with the HHI module at alpha 1 and the runtime's guidance."""
    hist = b.hist[rows]
    with torch.no_grad():
        emb = model.text_encoder.encode(b.text[rows]).to(hist.device)
    ctx = model.encode_contexts(b.partner[rows], b.present[rows], None, None, {"hhi": 1.0})
    z = model.sample_latent(hist, emb, ctx, {"hhi": 1.0}, DEFAULT_GUIDANCE, gen)
    return shown_joints(model.stats, model.vae.decode(hist, z))


def check_hhi_anchor(stage: str, anchor_weight: float, hhi_rollout: float) -> None:
    """Refuses an anchored HHI stage without a rollout loss: its anchor holds the segments that loss samples."""
    if stage == "hhi" and anchor_weight > 0.0 and hhi_rollout <= 0.0:
        with_rollout = ", ".join(n for n, r in WINDOW_RECIPES.items() if r.hhi_rollout > 0.0)
        raise RemogenError("an anchored hhi stage holds the segments its rollout loss samples, and this recipe has "
                           f"none (hhi_rollout 0): use --windows {with_rollout}, or drop --anchor")


def trainable_module(model: ReMoGenModel, stage: str) -> nn.Module:
    if stage == "decoder":
        return model.vae.decoder_parts()
    return {"vae": model.vae, "prior": model.denoiser, "hhi": model.mims["hhi"], "hsi": model.mims["hsi"],
            "fwsr": model.fwsr}[stage]


def freeze_for(model: ReMoGenModel, stage: str) -> list[nn.Parameter]:
    """Only the stage's own module trains; frozen modules stay in eval mode (no dropout)."""
    model.eval()
    for p in model.parameters():
        p.requires_grad_(False)
    mod = trainable_module(model, stage)
    mod.train()
    params = list(mod.parameters())
    for p in params:
        p.requires_grad_(True)
    return params


def _anchored_rows(b: Batch, out: torch.Tensor) -> torch.Tensor:
    """(B,) bool on `out`'s device: the batch's windows held to the starting file (all when the batch does not say)."""
    if b.anchored is None:
        return torch.ones(out.shape[0], dtype=torch.bool, device=out.device)
    return b.anchored.to(out.device)


class StageLoss(nn.Module):
    """forward(batch) -> (loss, parts); wrapping this module in DDP gives data-parallel training."""

    def __init__(self, model: ReMoGenModel, stage: str, shown_weight: float = DECODER_SHOWN_WEIGHT,
                 hhi_guidance: float = 0.0, anchor: ReMoGenModel | None = None, anchor_weight: float = 0.0,
                 hhi_rollout: float = 0.0,
                 rollout_costs: tuple[float, float, float] = (ROLLOUT_SEAM_WEIGHT, ROLLOUT_SKATE_WEIGHT,
                                                              ROLLOUT_GLIDE_WEIGHT),
                 rollout_arms: bool = True, text_jitter_cos: float = 1.0) -> None:
        super().__init__()
        self.model, self.stage = model, stage
        self.shown_weight = shown_weight   # the decoder stage's weight of the motion as shown (WindowRecipe)
        self.hhi_guidance = hhi_guidance   # the HHI stage's loss on the guided prediction (WindowRecipe)
        self.hhi_rollout = hhi_rollout     # the HHI stage's rollout clearance weight (WindowRecipe)
        self.rollout_costs = rollout_costs  # ... and the weights of its seam, skate and glide costs
        # ... and the ego's joints its clearance charge counts (None: all)
        self.clearance_joints = None if rollout_arms else \
            [i for name, i in JOINT_INDEX.items() if name not in ROLLOUT_REACHING_JOINTS]
        if anchor_weight > 0.0 and (anchor is None or stage not in ANCHOR_STAGES):
            raise ValueError(f"an anchored {stage} stage needs the starting model (stages {', '.join(ANCHOR_STAGES)})")
        check_hhi_anchor(stage, anchor_weight, hhi_rollout)
        # the starting file, frozen, whose output the windows it knew are held to (recipe.ANCHORED_KINDS)
        self.anchor = anchor.eval().requires_grad_(False) if anchor_weight > 0.0 else None
        self.anchor_weight = anchor_weight
        self.text_jitter_cos = text_jitter_cos   # captions turned to this cosine or more (text_jitter.py; 1: off)

    def forward(self, batch: Batch, gen: torch.Generator) -> tuple[torch.Tensor, dict[str, float]]:
        return getattr(self, f"_{self.stage if self.stage in ('vae', 'fwsr', 'decoder') else 'denoise'}")(batch, gen)

    def _vae(self, b: Batch, gen: torch.Generator):
        vae = self.model.vae
        mu, logvar = vae.encode(b.hist, b.fut)
        z = mu + noise(mu.shape, gen, mu.device) * torch.exp(0.5 * logvar)
        rec = nn.functional.smooth_l1_loss(vae.decode(b.hist, z), b.fut)
        kl = 0.5 * (mu.pow(2) + logvar.exp() - 1 - logvar).mean()
        return rec + KL_WEIGHT * kl, {"rec": float(rec.detach()), "kl": float(kl.detach())}

    def _decoder(self, b: Batch, gen: torch.Generator):
        vae = self.model.vae
        with torch.no_grad():
            mu, logvar = vae.encode(b.hist, b.fut)
        z = mu + noise(mu.shape, gen, mu.device) * torch.exp(0.5 * logvar)
        dec = vae.decode(b.hist, z)
        rec = nn.functional.smooth_l1_loss(dec, b.fut)
        shown = shown_joint_error(self.model.stats, dec, b.fut)
        w = torch.ones_like(shown)
        w[:len(DECODER_FIRST_FRAMES)] = torch.tensor(DECODER_FIRST_FRAMES, dtype=w.dtype)
        shown_loss = (shown * w / w.mean()).mean()
        parts = {"rec": float(rec.detach()), "shown_m": float(shown.mean().detach()),
                 "first_m": float(shown[0].detach())}
        loss = rec + self.shown_weight * shown_loss
        if self.anchor is not None:
            keep = _anchored_rows(b, dec)
            held = dec.sum() * 0.0
            if bool(keep.any()):
                with torch.no_grad():
                    before = self.anchor.vae.decode(b.hist[keep], z[keep])
                held = nn.functional.smooth_l1_loss(dec[keep], before)
            parts["anchor"] = float(held.detach())
            loss = loss + self.anchor_weight * held
        return loss, parts

    def text_inputs(self, b: Batch, gen: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
        """The captions' embeddings and which of them are dropped (TEXT_DROP) for classifier-free guidance."""
        m = self.model
        dev = m.denoiser.null_text.device
        emb = jitter_text(m.text_encoder.encode(b.text), self.text_jitter_cos, TEXT_JITTER_SHARE, gen).to(dev)
        drop = (torch.rand(len(b.text), generator=gen) < TEXT_DROP).to(dev)
        return emb, drop

    def contexts(self, b: Batch) -> tuple[Contexts, dict[str, float]]:
        m = self.model
        if self.stage == "hhi":
            return m.encode_contexts(b.partner, b.present, None, None, {"hhi": 1.0}), {"hhi": 1.0}
        if self.stage == "hsi":
            return m.encode_contexts(None, None, b.occupancy, b.goal, {"hsi": 1.0}), {"hsi": 1.0}
        return Contexts({}), {}

    def _denoise(self, b: Batch, gen: torch.Generator):
        m = self.model
        with torch.no_grad():
            z0, _ = m.vae.encode(b.hist, b.fut)
        t = torch.randint(0, m.cfg.diffusion_steps, (z0.shape[0],), generator=gen).to(z0.device)
        z_t = m.schedule.q_sample(z0, t, noise(z0.shape, gen, z0.device))
        ctx, alpha = self.contexts(b)
        inject = m.injector(ctx, alpha)
        if self.stage == "hhi" and self.hhi_guidance > 1.0:
            x0 = self._guided(b, z_t, t, inject)
        else:
            text = self.text_inputs(b, gen)
            x0 = m.denoiser(z_t, t, b.hist, m.denoiser.text_tokens(*text), inject)
        latent = nn.functional.mse_loss(x0, z0)
        rec = nn.functional.smooth_l1_loss(m.vae.decode(b.hist, x0), b.fut)
        parts = {"latent": float(latent.detach()), "rec": float(rec.detach())}
        loss = latent + rec
        if self.anchor is not None and self.stage == "prior":   # no interaction module to inject
            kept = self._prior_anchor(b, z_t, t, text, x0)
            parts["anchor"] = float(kept.detach())
            loss = loss + self.anchor_weight * kept
        if self.stage == "hhi" and self.hhi_rollout > 0.0 and b.partner_future is not None:
            rolled = self._rollout_loss(b, gen)
            parts.update({k: float(v.detach()) for k, v in rolled.items()})
            seam, skate, glide = self.rollout_costs
            loss = loss + self.hhi_rollout * rolled["clear"] + seam * rolled["seam"] + skate * rolled["skate"] \
                + glide * rolled["glide"] + self.anchor_weight * rolled["kept"]
        return loss, parts

    def _rollout_loss(self, b: Batch, gen: torch.Generator) -> dict[str, torch.Tensor]:
        """What the segments the model samples for the first ROLLOUT_ROWS windows cost, sampled as the runtime samples
        them (every denoising step, guidance with its eased last step, the module at alpha 1; the gradient through
        all of it): "clear" the clearance charge (clearance_charge); control's costs: "seam" the joints' acceleration
        across the segment's start, "skate" the planted toes' slide and "glide" the pelvis's accelerations past a
        walk's (measured: without them the module learned to slide, then to glide out of the way); "kept" (with an
        anchor) how far the segments moved from those the starting module samples from the same noise. The
        denoising loss scores one step from a real future, and what it fits there did not come out of the sampled
        steps from a still history (docs/HISTORY.md, "Learning the controlled reaction")."""
        rows = slice(0, min(ROLLOUT_ROWS, b.hist.shape[0]))   # the batch's order is random
        drawn_from = gen.get_state()
        ego = rollout_joints(self.model, b, rows, gen)
        out = {"clear": clearance_charge(ego, b.partner_future[rows].to(ego.device),
                                         b.future_present[rows].to(ego.device), self.clearance_joints)}
        m = self.model
        before = shown_joints(m.stats, b.hist[rows, -2:])   # (R, 2, 22, 3): the history's last two frames
        out["seam"] = seam_cost(ego, before[:, 1], before[:, 0]).mean()
        cc = ControlConfig()
        out["skate"] = foot_cost(ego, before[:, 1], cc).mean()
        out["glide"] = glide_cost(ego[..., 0, :2], before[:, :, 0, :2], cc.glide_accel / FPS ** 2).mean()
        out["kept"] = ego.sum() * 0.0
        if self.anchor is not None:
            after = gen.get_state()
            gen.set_state(drawn_from)          # the same noise for the starting module
            with torch.no_grad():
                start = rollout_joints(self.anchor, b, rows, gen)
            gen.set_state(after)
            out["kept"] = (ego - start).pow(2).sum(-1).mean()
        return out

    def _prior_anchor(self, b: Batch, z_t: torch.Tensor, t: torch.Tensor, text: tuple[torch.Tensor, torch.Tensor],
                      x0: torch.Tensor) -> torch.Tensor:
        """How far the prior's predictions on the anchored windows moved from the starting prior's: the prediction
        trained on (caption dropout included) and the unconditional one. The runtime's guidance scales their
        difference by 6, so a small move of either shows in the motion (measured: holding the first alone let the run
        kind slow and the standing ego drift)."""
        m, start = self.model, self.anchor
        keep = _anchored_rows(b, x0)
        if not bool(keep.any()):
            return x0.sum() * 0.0
        args = (z_t[keep], t[keep], b.hist[keep])
        emb, drop = text[0][keep], text[1][keep]
        null = torch.ones_like(drop)
        with torch.no_grad():
            before = start.denoiser(*args, start.denoiser.text_tokens(emb, drop), None)
            before_u = start.denoiser(*args, start.denoiser.text_tokens(emb, null), None)
        now_u = m.denoiser(*args, m.denoiser.text_tokens(emb, null), None)
        return nn.functional.mse_loss(x0[keep], before) + nn.functional.mse_loss(now_u, before_u)

    def _guided(self, b: Batch, z_t: torch.Tensor, t: torch.Tensor, inject: Callable | None) -> torch.Tensor:
        """The x0 prediction guided as the runtime guides it: both passes with the module, the text's push scaled.
        No caption dropout here: the unconditional pass is the dropped caption."""
        m = self.model
        emb = m.text_encoder.encode(b.text).to(z_t.device)
        keep = torch.zeros(len(b.text), dtype=torch.bool, device=z_t.device)
        cond = m.denoiser(z_t, t, b.hist, m.denoiser.text_tokens(emb, keep), inject)
        uncond = m.denoiser(z_t, t, b.hist, m.denoiser.text_tokens(emb, ~keep), inject)
        return uncond + self.hhi_guidance * (cond - uncond)

    def _fwsr(self, b: Batch, gen: torch.Generator):
        m = self.model
        with torch.no_grad():  # the segment latent as the frozen generator makes it online
            text = m.text_encoder.encode(b.text).to(b.hist.device)
            ctx = m.encode_contexts(b.partner, b.present, None, None, {"hhi": 1.0}) \
                if b.partner is not None else Contexts({})
            z0 = m.sample_latent(b.hist, text, ctx, {"hhi": 1.0}, 5.0, gen)
            recent = own_recent_frames(m, b, z0, gen)
        frame = b.frame
        z = m.fwsr(z0, recent, b.recent_partner, b.recent_present, frame)
        dec = m.vae.decode(b.hist, z)
        idx = torch.arange(dec.shape[0], device=dec.device)
        target = nn.functional.smooth_l1_loss(dec[idx, frame], b.fut[idx, frame])
        # the later frames of the refined decode matter too (they seed the next refinements)
        later = (torch.arange(dec.shape[1], device=dec.device).unsqueeze(0) >= frame.unsqueeze(1)).float().unsqueeze(-1)
        rest = (nn.functional.smooth_l1_loss(dec, b.fut, reduction="none") * later).sum() / \
            (later.sum() * dec.shape[-1])
        return target + 0.5 * rest, {"frame": float(target.detach()), "later": float(rest.detach())}
