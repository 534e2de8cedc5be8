"""ReMoGenModel: the networks of one checkpoint and the operations the session and training use."""
from __future__ import annotations

from typing import Callable

import torch
from torch import nn

from .checks import Checked, check_final_guidance_min_speed, check_final_guidance_share
from .config import MODULE_NAMES, ModelConfig
from .diffusion import CosineSchedule
from .errors import DEFAULT_FINAL_GUIDANCE_MIN_SPEED, DEFAULT_FINAL_GUIDANCE_SHARE
from .features import ROOT_T, FeatureStats
from .nets.denoiser import LatentDenoiser
from .nets.fwsr import FrameRefiner
from .nets.interaction import MetaInteractionModule, OthersEncoder, SceneEncoder, compose_residuals
from .nets.vae import MotionVAE
from .prompt import prompt_warning
from .text import TextEncoder, build_text_encoder


def non_finite_weight(state_dict: dict) -> str | None:
    """The name of the first floating-point tensor holding NaN or inf, or None."""
    for name, t in state_dict.items():
        if torch.is_tensor(t) and t.is_floating_point() and not bool(torch.isfinite(t).all()):
            return name
    return None


class Contexts:
    """Encoded interaction context of one segment: per module (tokens, mask or None).

    In a batch of egos a module may serve only some rows: `rows[name]` then holds their batch indices (the
    tokens are those rows' only); a module without an entry serves every row. Caches what stays constant
    over the segment's denoising steps: the batch-repeated copies for classifier-free guidance and each
    block's cross-attention keys/values.
    """

    def __init__(self, items: dict[str, tuple[torch.Tensor, torch.Tensor | None]],
                 rows: dict[str, torch.Tensor] | None = None, batch: int = 0) -> None:
        self.items = items
        self.rows = rows or {}
        self.batch = batch       # the batch size the row indices refer to (needed only with rows)
        self._repeats: dict[int, Contexts] = {1: self}
        self._kv: dict[tuple[str, int], tuple[torch.Tensor, torch.Tensor]] = {}

    def repeat(self, n: int) -> "Contexts":
        if n not in self._repeats:
            rows = {k: torch.cat([r + i * self.batch for i in range(n)]) for k, r in self.rows.items()}
            self._repeats[n] = Contexts({k: (t.repeat(n, 1, 1), None if m is None else m.repeat(n, 1))
                                         for k, (t, m) in self.items.items()}, rows, n * self.batch)
        return self._repeats[n]

    def kv(self, name: str, layer: int, block) -> tuple[torch.Tensor, torch.Tensor]:
        key = (name, layer)
        if key not in self._kv:
            self._kv[key] = block.cross.context_kv(self.items[name][0])
        return self._kv[key]


def _rows_of(on: torch.Tensor) -> torch.Tensor | None | bool:
    """The rows a module serves: None for all of them, their indices for some, False for none."""
    if bool(on.all()):
        return None
    idx = torch.nonzero(on).flatten()
    return idx if idx.numel() else False


def _alpha_on(active: dict[str, float] | list[dict[str, float]], name: str, b: int,
              device: torch.device | None = None) -> torch.Tensor:
    """(b,) bool: which rows give module `name` a non-zero alpha (one dict: all rows alike)."""
    if isinstance(active, dict):
        return torch.full((b,), active.get(name, 0.0) != 0.0, device=device)
    return torch.tensor([a.get(name, 0.0) != 0.0 for a in active], dtype=torch.bool, device=device)


def _per_row(values: list[float], n: int, dtype: torch.dtype, device: torch.device | None = None
             ) -> float | torch.Tensor:
    """One number when every row shares it (the single-ego path stays exactly as it was), else (n*B, 1, 1)."""
    if all(v == values[0] for v in values):
        return values[0]
    return torch.tensor(values, dtype=dtype, device=device).repeat(n).view(-1, 1, 1)


def final_step_guidance(guidance: float | list[float], share: float,
                        eased: list[bool] | None = None) -> float | list[float]:
    """The guidance of the last denoising step: `share` of each scale's push past the conditional pass (1), for
    the rows `eased` marks (all when None); the others keep their scale. One scale stays one scale when the rows
    agree."""
    if share == 1.0 or (eased is not None and not any(eased)):
        return guidance          # the scales themselves, bit for bit (1 + (g - 1) can round)
    one = isinstance(guidance, (int, float))
    rows = [float(g) for g in guidance] if not one else [float(guidance)] * (len(eased) if eased is not None else 1)
    marks = eased if eased is not None else [True] * len(rows)
    out = [1.0 + (g - 1.0) * share if m else g for g, m in zip(rows, marks)]
    return out[0] if one and len(set(out)) == 1 else out


def history_speed(model: "ReMoGenModel", hist_n: torch.Tensor) -> torch.Tensor:
    """(B,) horizontal pelvis speed (m/s) from the first to the last frame of normalised histories (B, H, D)."""
    root = model.stats.denormalize(hist_n)[..., ROOT_T]
    return (root[:, -1, :2] - root[:, 0, :2]).norm(dim=-1) * model.fps / max(root.shape[1] - 1, 1)


class ReMoGenModel(nn.Module):
    fps = 10

    def __init__(self, cfg: ModelConfig) -> None:
        super().__init__()
        self.cfg = cfg
        self.stats = FeatureStats(cfg.feature_dim)
        self.vae = MotionVAE(cfg)
        self.denoiser = LatentDenoiser(cfg)
        d, dc = cfg.den_dim, cfg.mim_dim
        self.mims = nn.ModuleDict({
            "hhi": MetaInteractionModule(OthersEncoder(cfg.partner_window, dc, cfg.partner_line_cues),
                                         cfg.inject_layers, d, dc,
                                         cfg.mim_heads, cfg.rel_omega, cfg.dropout, cfg.mim_ff_mult),
            "hsi": MetaInteractionModule(SceneEncoder(cfg.voxel_resolution, cfg.voxel_patch, dc, cfg.mim_heads,
                                                      cfg.scene_layers, cfg.dropout),
                                         cfg.inject_layers, d, dc, cfg.mim_heads, cfg.rel_omega, cfg.dropout,
                                         cfg.mim_ff_mult),
        })
        self.fwsr = FrameRefiner(cfg)
        self.schedule = CosineSchedule(cfg.diffusion_steps)
        self.text_encoder: TextEncoder = build_text_encoder(cfg.text)
        # how the runtime reads prompts (text_blend.py; set from the model file's meta): None reads them as
        # they are, as training does
        self.prompt_blend: TextEncoder | None = None
        self.meta: dict = {}
        self.diffusion_dtype = torch.float32
        self._int8 = False   # the denoiser's linears were swapped for quantised ones (set_precision("int8"))
        # how much guidance the last denoising step keeps, and for which egos (errors.py says why)
        self.final_guidance_share = DEFAULT_FINAL_GUIDANCE_SHARE
        self.final_guidance_min_speed = DEFAULT_FINAL_GUIDANCE_MIN_SPEED

    final_guidance_share = Checked(check_final_guidance_share,
                                   "The share of the guidance's push the last denoising step keeps, 0..1.")
    final_guidance_min_speed = Checked(check_final_guidance_min_speed,
                                       "The last step is eased only for egos whose history moves this fast (m/s).")

    def set_precision(self, precision: str) -> "ReMoGenModel":
        """"fp32" (default), "bf16" or "int8" for the diffusion networks. Inference only.

        bf16: the denoiser and Meta-Interaction Modules in bfloat16; ~1.8x faster for the paper-sized
        denoiser on CPUs with AVX512-BF16, slower where bf16 is emulated (no AVX-512).
        int8: the denoiser's linear layers with int8 weights and dynamically quantised activations
        (PyTorch's fbgemm kernels through torch.ao.quantization.quantize_dynamic). It is the only int8
        path measured faster here: paper preset fwsr 20.1 ms against 27.2 fp32 on a host without AVX-512;
        torchao 0.18 in eager mode gave no gain. torch.ao.quantization is deprecated in favour of torchao,
        so a PyTorch without it gets a clear error. The Meta-Interaction Modules, VAE decoder and FWSR stay
        float32 (their outputs are the visible motion; the MIM cross-attention caches on its weights).
        The switch to int8 cannot be undone on the same model object.
        """
        from .errors import InputError
        if precision not in ("fp32", "bf16", "int8"):
            raise InputError(f"precision must be 'fp32', 'bf16' or 'int8', got {precision!r}")
        if self._int8 and precision != "int8":
            raise InputError("this model's denoiser is already int8; load it again for another precision")
        self.diffusion_dtype = torch.bfloat16 if precision == "bf16" else torch.float32
        self.mims.to(self.diffusion_dtype)
        if precision != "int8":
            self.denoiser.to(self.diffusion_dtype)
        elif not self._int8:
            try:
                import warnings
                from torch.ao.quantization import quantize_dynamic
            except ImportError as exc:
                raise InputError("precision='int8' needs torch.ao.quantization, which this PyTorch lacks; "
                                 "use 'fp32'") from exc
            with warnings.catch_warnings():   # its deprecation notices (documented above), once per load
                warnings.simplefilter("ignore")
                self.denoiser = quantize_dynamic(self.denoiser.float(), {nn.Linear}, dtype=torch.qint8)
            self._int8 = True
        return self

    # ------------------------------------------------------------------ conditioning
    def warm_text(self) -> None:
        """Build now what reading a prompt needs (the blend's phrasing vectors, about 0.45 s), so that a live rig's
        first prompt does not stall a frame."""
        if self.prompt_blend is not None:
            self.prompt_blend.warm()

    def nearest_phrasing(self, text: str) -> tuple[str, float] | None:
        """The training phrasing a prompt leans toward and its cosine with the prompt (text_blend.py), to show a
        user how a prompt is read; None when the file reads prompts as they are, or for a prompt of no known word."""
        return None if self.prompt_blend is None else self.prompt_blend.nearest(text)

    def encode_text(self, text: str) -> torch.Tensor:
        """A prompt's vector as the runtime reads it (blended toward the training phrasings when the file says so)."""
        return (self.prompt_blend or self.text_encoder).encode([text])

    @staticmethod
    def text_warning(text: str) -> str | None:
        """One line when the text encoder cannot read `text` (prompt.py), else None."""
        return prompt_warning(text)

    def encode_contexts(self, partner: torch.Tensor | None, present: torch.Tensor | None,
                        occupancy: torch.Tensor | None, goal: torch.Tensor | None,
                        active: dict[str, float] | list[dict[str, float]],
                        has_goal: torch.Tensor | None = None) -> Contexts:
        """Encode only what the active (alpha != 0) modules need; absent cues switch a module off.

        `active`: one alpha dict for the whole batch, or one per row (a group of egos: a module then runs
        only on the rows whose alpha and cue call for it). has_goal (B,) marks the rows whose goal is real
        (default: every row when `goal` is given).
        """
        items: dict[str, tuple[torch.Tensor, torch.Tensor | None]] = {}
        rows: dict[str, torch.Tensor] = {}
        dt = self.diffusion_dtype
        per_row = not isinstance(active, dict)
        b = 0
        if partner is not None and present is not None:
            b = partner.shape[0]
            cue = present.any(1) if per_row else present.any().expand(b)
            r = _rows_of(cue & _alpha_on(active, "hhi", b, cue.device))
            if r is not False:
                p, m = (partner, present) if r is None else (partner[r], present[r])
                items["hhi"] = (self.mims["hhi"].encoder(p.to(dt), m), m)
                if r is not None:
                    rows["hhi"] = r
        if occupancy is not None or goal is not None:
            b = (occupancy if occupancy is not None else goal).shape[0]
            dev = (occupancy if occupancy is not None else goal).device
            has = has_goal if has_goal is not None else torch.full((b,), goal is not None, device=dev)
            r = _rows_of((has | (occupancy is not None)) & _alpha_on(active, "hsi", b, dev))
            if r is not False:
                res = self.cfg.voxel_resolution
                occ = occupancy if occupancy is not None else torch.zeros(b, res, res, res, device=dev)
                g = goal if goal is not None else torch.zeros(b, 3, device=dev)
                if r is not None:
                    occ, g, has = occ[r], g[r], has[r]
                    rows["hsi"] = r
                items["hsi"] = (self.mims["hsi"].encoder(occ.to(dt), g.to(dt), has), None)
        return Contexts(items, rows, b)

    # ------------------------------------------------------------------ denoising
    def predict_x0(self, z_t: torch.Tensor, t: int, hist: torch.Tensor, text_emb: torch.Tensor,
                   contexts: Contexts, alpha: dict[str, float] | list[dict[str, float]],
                   guidance: float | list[float], cache: dict | None = None) -> torch.Tensor:
        """x0 with classifier-free guidance: conditional and unconditional passes as one batch.

        A group of egos passes one text embedding, alpha dict and guidance per row. `cache` (owned by a
        DiffusionJob) keeps the tokens that do not change between a segment's denoising steps (text +
        history tokens, all step embeddings).
        """
        b = z_t.shape[0]
        dt = self.diffusion_dtype
        scales = [float(guidance)] if isinstance(guidance, (int, float)) else [float(g) for g in guidance]
        use_cfg = any(g != 1.0 for g in scales)
        n = 2 if use_cfg else 1
        cache = {} if cache is None else cache
        if ("cond", n) not in cache:
            drop = torch.zeros(n * b, dtype=torch.bool, device=z_t.device)
            drop[b:] = True
            text_tok = self.denoiser.text_tokens(text_emb.to(dt).expand(b, -1).repeat(n, 1), drop)
            cache[("cond", n)] = self.denoiser.condition_tokens(hist.to(dt).repeat(n, 1, 1), text_tok)
        if ("temb", n) not in cache:
            steps = torch.arange(self.cfg.diffusion_steps, device=z_t.device).repeat_interleave(n * b)
            cache[("temb", n)] = self.denoiser.time_tokens(steps).view(self.cfg.diffusion_steps, n * b, 1, -1)
        ctx = contexts.repeat(n)
        inject = self.injector(ctx, alpha)
        x0 = self.denoiser.forward_tokens(z_t.to(dt).repeat(n, 1, 1), cache[("temb", n)][t], cache[("cond", n)],
                                          inject).float()
        if not use_cfg:
            return x0
        cond, uncond = x0[:b], x0[b:]
        w = _per_row(scales, 1, torch.float32, x0.device)
        guided = uncond + w * (cond - uncond)
        # a row with guidance 1 is its conditional pass exactly, as it is without the others
        return guided if not torch.is_tensor(w) else torch.where(w == 1.0, cond, guided)

    def injector(self, ctx: Contexts, alpha: dict[str, float] | list[dict[str, float]]):
        """The denoiser hook adding the composed Meta-Interaction residuals; None when no module is active.

        alpha: one dict for every row, or one per row of the (unrepeated) batch.
        """
        alphas = [alpha] if isinstance(alpha, dict) else list(alpha)
        names = [k for k in MODULE_NAMES if k in ctx.items and any(a.get(k, 0.0) != 0.0 for a in alphas)]
        if not names:
            return None
        values = {k: [a.get(k, 0.0) for a in alphas] for k in names}

        def inject(layer: int, h: torch.Tensor) -> torch.Tensor | None:
            deltas, weights = [], []
            for k in names:
                block = self.mims[k].block_at(layer)
                if block is not None:
                    tok, mask = ctx.items[k]
                    rows = ctx.rows.get(k)
                    if rows is None:
                        deltas.append(block(h, tok, mask, ctx.kv(k, layer, block)))
                    else:     # the rows this module serves; the others get no residual from it
                        delta = torch.zeros_like(h)
                        delta[rows] = block(h[rows], tok, mask, ctx.kv(k, layer, block))
                        deltas.append(delta)
                    weights.append(_per_row(values[k], h.shape[0] // len(alphas), h.dtype, h.device))
            return compose_residuals(deltas, weights)

        return inject

    def sample_latent(self, hist: torch.Tensor, text_emb: torch.Tensor, contexts: Contexts,
                      alpha: dict[str, float], guidance: float, generator: torch.Generator) -> torch.Tensor:
        """Full reverse diffusion for one segment (all steps at once)."""
        job = DiffusionJob(self, hist, text_emb, contexts, alpha, guidance, generator,
                           final_guidance_share=self.final_guidance_share,
                           final_guidance_min_speed=self.final_guidance_min_speed)
        job.advance(self.cfg.diffusion_steps)
        return job.result

    # ------------------------------------------------------------------ decoding / refinement
    def decode(self, hist: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
        return self.vae.decode(hist, z)

    def refine(self, z0: torch.Tensor, hist: torch.Tensor, partner: torch.Tensor, present: torch.Tensor,
               frame: int) -> torch.Tensor:
        return self.fwsr(z0, hist, partner, present,
                         torch.full((z0.shape[0],), frame, dtype=torch.long, device=z0.device))

    @torch.no_grad()
    def compute_decoder_sensitivity(self, hist: torch.Tensor, z: torch.Tensor, eps: float = 1e-2) -> torch.Tensor:
        """Finite-difference sensitivity of the decoder per latent entry, averaged over samples.

        s_d = mean_b || D(h_b, z_b + eps e_d) - D(h_b, z_b) || / eps, rescaled to mean 1 so beta keeps
        one meaning across checkpoints. Stored in the FWSR buffer (computed once per checkpoint).
        """
        was_training = self.training
        self.eval()
        n, lt, dz = z.shape
        base = self.decode(hist, z)
        sens = torch.zeros(lt * dz)
        eye = torch.eye(lt * dz).reshape(lt * dz, lt, dz) * eps
        for i in range(n):
            zp = z[i:i + 1] + eye
            out = self.decode(hist[i:i + 1].expand(lt * dz, -1, -1), zp)
            sens += (out - base[i:i + 1]).flatten(1).norm(dim=1) / eps
        sens = sens / n
        sens = sens / sens.mean().clamp_min(1e-12)
        self.fwsr.sensitivity.copy_(sens.reshape(lt, dz))
        self.train(was_training)
        return self.fwsr.sensitivity


class DiffusionJob:
    """The reverse diffusion of one segment as a resumable object, so its steps can be spread over frames.

    With `steer` (test-time control), the predicted x0 of the last `steered_steps` denoising steps is moved
    by it, and then the clean latent takes `final_steers` more of its steps: those last ones stay in the
    result in full, where earlier ones are partly undone by the denoising that follows them.

    A group of egos is one job: one alpha dict, guidance and generator per row (each row then draws its
    noise from its own generator, exactly as it would alone). The last denoising step takes the guidance
    eased by `final_guidance_share` (`final_step_guidance`) in the rows whose history moves at least
    `final_guidance_min_speed`; the model's settings stand in for those not given.
    """

    def __init__(self, model: ReMoGenModel, hist: torch.Tensor, text_emb: torch.Tensor, contexts: Contexts,
                 alpha: dict[str, float] | list[dict[str, float]], guidance: float | list[float],
                 generator: torch.Generator | list[torch.Generator] | NoiseDraws,
                 steer: Callable[[torch.Tensor], torch.Tensor] | None = None, steered_steps: int = 0,
                 final_steers: int = 0, final_guidance_share: float | None = None,
                 final_guidance_min_speed: float | None = None) -> None:
        self.model, self.hist, self.text_emb, self.contexts = model, hist, text_emb, contexts
        self.steer = steer
        self.steered_steps = steered_steps if steer is not None else 0
        self.final_steers = final_steers if steer is not None else 0
        self._cache: dict = {}
        self.alpha = dict(alpha) if isinstance(alpha, dict) else [dict(a) for a in alpha]
        self.guidance = float(guidance) if isinstance(guidance, (int, float)) else [float(g) for g in guidance]
        share = model.final_guidance_share if final_guidance_share is None else final_guidance_share
        min_speed = model.final_guidance_min_speed if final_guidance_min_speed is None else final_guidance_min_speed
        eased = None if share == 1.0 else (history_speed(model, hist) >= min_speed).tolist()
        self.final_guidance = final_step_guidance(self.guidance, share, eased)
        self.gen = generator
        cfg = model.cfg
        shape = (hist.shape[0], cfg.latent_tokens, cfg.latent_dim)
        self.z = noise(shape, generator, hist.device)
        self.t = cfg.diffusion_steps - 1
        self._clean: torch.Tensor | None = None     # the denoised latent while final steers remain
        self._steers_left = self.final_steers
        self.result: torch.Tensor | None = None

    @property
    def total_steps(self) -> int:
        """Units of work from start to result: denoising steps plus final steering steps."""
        return self.model.cfg.diffusion_steps + self.final_steers

    @property
    def done(self) -> bool:
        return self.result is not None

    def snapshot(self) -> tuple:
        """The progress `advance` changes (not a shared generator: its owner saves that; draws made in advance
        are the job's own, so where it is in them is saved here)."""
        taken = self.gen.taken if isinstance(self.gen, NoiseDraws) else None
        return self.z, self.t, self._clean, self._steers_left, self.result, dict(self._cache), taken

    def restore(self, snap: tuple) -> None:
        self.z, self.t, self._clean, self._steers_left, self.result, cache, taken = snap
        self._cache = dict(cache)
        if taken is not None:
            self.gen.taken = taken

    def advance(self, steps: int) -> None:
        for _ in range(steps):
            if self.done:
                return
            if self._clean is not None:
                self._clean = self.steer(self._clean)
                self._steers_left -= 1
            else:
                guidance = self.final_guidance if self.t == 0 else self.guidance
                x0 = self.model.predict_x0(self.z, self.t, self.hist, self.text_emb, self.contexts,
                                           self.alpha, guidance, self._cache)
                if self.t < self.steered_steps:
                    x0 = self.steer(x0)
                if self.t == 0:
                    self._clean = x0
                else:
                    eps = noise(self.z.shape, self.gen, self.z.device)
                    self.z = self.model.schedule.step(self.z, self.t, x0, eps)
                    self.t -= 1
            if self._clean is not None and self._steers_left == 0:
                settle = getattr(self.steer, "settle", None)     # a LatentSteer checks its last step too
                self.result = settle(self._clean) if settle is not None and self.final_steers else self._clean


class NoiseDraws:
    """A job's noise drawn in advance, handed out in order: the very numbers its generators would have given
    when the job asked for them, as long as nothing else draws from those generators meanwhile (each ego's
    generator serves only its jobs). Lets a job run elsewhere (job_worker.py) with the same result."""

    def __init__(self, generator: torch.Generator | list[torch.Generator], shape: tuple[int, ...],
                 count: int) -> None:
        self.draws = [noise(shape, generator) for _ in range(count)]
        self.taken = 0

    def __getstate__(self) -> dict:
        # one tensor to pickle instead of one per draw (each tensor costs tens of microseconds to pickle)
        return {"draws": torch.stack(self.draws) if self.draws else None, "taken": self.taken}

    def __setstate__(self, state: dict) -> None:
        self.draws = [] if state["draws"] is None else list(state["draws"].unbind(0))
        self.taken = state["taken"]

    def take(self, shape: tuple[int, ...]) -> torch.Tensor:
        if self.taken >= len(self.draws) or tuple(self.draws[self.taken].shape) != tuple(shape):
            raise RuntimeError("a job asked for more or other noise than was drawn for it")
        self.taken += 1
        return self.draws[self.taken - 1]


def job_draws(model: "ReMoGenModel", generator: torch.Generator | list[torch.Generator], batch: int) -> NoiseDraws:
    """Every draw a DiffusionJob of `batch` rows makes: its starting latent, then one per denoising step but the
    last."""
    cfg = model.cfg
    return NoiseDraws(generator, (batch, cfg.latent_tokens, cfg.latent_dim), cfg.diffusion_steps)


def noise(shape: tuple[int, ...], generator: torch.Generator | list[torch.Generator] | NoiseDraws,
          device: torch.device | None = None) -> torch.Tensor:
    """Standard normal noise on `device`; with one generator per row, each row drawn from its own. Drawn from CPU
    generators whatever the device, so a seed gives the same draws on a GPU as on the CPU."""
    if isinstance(generator, NoiseDraws):
        out = generator.take(shape)
    elif isinstance(generator, torch.Generator):
        out = torch.randn(shape, generator=generator)
    else:
        out = torch.cat([torch.randn((1,) + tuple(shape[1:]), generator=g) for g in generator])
    return out if device is None else out.to(device)
