"""The eval-mode fast path of the transformer layers (nets.common.FastEval) computes exactly the module path."""
import pytest
import torch

from model_runtime import load_model
from model_runtime.nets.common import FastEval, TransformerLayer
from model_runtime.nets.interaction import MetaInteractionBlock


def _module_path(layer: FastEval, *args):
    layer._weights = ()          # an empty cache means "use the submodules" (see FastEval.eval_weights)
    try:
        return layer(*args)
    finally:
        layer._weights = None


@torch.no_grad()
def test_fast_path_is_bit_identical_to_the_module_path():
    torch.manual_seed(0)
    layer = TransformerLayer(32, 4, 64, dropout=0.1).eval()
    x = torch.randn(2, 5, 32)
    assert layer.eval_weights() is not None
    assert torch.equal(layer(x), _module_path(layer, x))
    block = MetaInteractionBlock(32, 16, 4, omega=0.25, dropout=0.1).eval()
    for p in block.parameters():          # zero-initialised parts would hide a wrong order of operations
        p.normal_(0, 0.2)
    h, ctx = torch.randn(2, 5, 32), torch.randn(2, 7, 16)
    mask = torch.ones(2, 7, dtype=torch.bool)
    mask[0, :3] = False
    assert torch.equal(block(h, ctx, mask), _module_path(block, h, ctx, mask))


def test_training_uses_the_modules_with_dropout():
    torch.manual_seed(0)
    layer = TransformerLayer(32, 4, 64, dropout=0.5).train()
    x = torch.randn(2, 5, 32)
    assert layer.eval_weights() is None
    assert not torch.equal(layer(x), layer(x))     # dropout is live
    layer.eval()
    assert torch.equal(layer(x), layer(x))


@pytest.mark.parametrize("precision", ["bf16", "int8"])
def test_the_cache_follows_precision_changes(precision):
    model = load_model(config="tiny").eval()
    block = model.mims["hhi"].blocks[0]
    assert block.eval_weights()[1].dtype == torch.float32
    model.set_precision(precision)      # no eval() after: the switch itself must drop the cache
    if precision == "bf16":
        assert block.eval_weights()[1].dtype == torch.bfloat16
        assert all(l.eval_weights()[1].dtype == torch.bfloat16 for l in model.denoiser.layers)
    else:   # quantised linears: the layer must run them, not cached float weights
        assert all(l.eval_weights() is None for l in model.denoiser.layers)
