"""splat: triangle model, differentiable rasteriser (reference / CPU / CUDA), losses, training, export."""
