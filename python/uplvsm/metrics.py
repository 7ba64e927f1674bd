"""Image-quality metrics with the community's exact definitions: PSNR, scikit-image's SSIM (without scikit-image)
and LPIPS v0.1 (with weight files you give). Tensors [..., C, H, W] in [0, 1], on the CPU or CUDA."""
import functools as _functools

from ._uplvsm.metrics import LPIPS, psnr, ssim

__all__ = ["psnr", "ssim", "lpips", "LPIPS"]


@_functools.lru_cache(maxsize=4)
def _lpips_net(net, backbone, lin, device):
    return LPIPS(net=net, backbone=backbone, lin=lin, device=device)


def lpips(pred, gt, *, backbone, lin, net="vgg"):
    """LPIPS v0.1 of image pairs pred, gt [..., 3, H, W] in [0, 1]: float32 [...].

    backbone: torchvision features weights of `net` ("vgg" or "alex"); lin: the official lpips lin weights
    (lpips/weights/v0.1/<net>.pth) or a safetensors copy. The network is loaded once per (net, files, device);
    keep an uplvsm.metrics.LPIPS yourself to control that."""
    return _lpips_net(net, str(backbone), str(lin), str(pred.device))(pred, gt)
