"""Where the LPIPS weights come from, and ``lts weights download``, which fetches and checks them.

The weights file is one torch state dict (:mod:`eval.lpips_net`): torchvision's ImageNet AlexNet
trunk and the lpips package's v0.1 "alex" heads. :func:`load_lpips` looks, in order, at:

1. the file given (``lts eval --lpips-weights PATH``);
2. the cache file ``$LTS_CACHE_DIR/lpips_alex.pt`` (default ``~/.cache/lidar-ts/lpips_alex.pt``),
   which ``lts weights download`` writes;
3. torchvision's ``alexnet-owt-7be5be79.pth`` in the torch hub cache together with the ``alex.pth``
   the lpips package carries, when both are on this machine.

Nothing is downloaded at evaluation time. The download checks each file's size and SHA-256
against :data:`ALEXNET` and :data:`LPIPS_HEADS`.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import shutil
import tempfile
import urllib.error
import urllib.request
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import torch

from eval.lpips_net import LpipsAlex, combined_state, load_network, network_from_state, read_torch_file
from rig.errors import InputError
from rig.user_cache import cache_dir

WEIGHTS_FILE = "lpips_alex.pt"
#: The reason LPIPS is null when no weights are found.
HOW_TO_GET = (
    "no LPIPS weights on this machine: run 'lts weights download' once (needs internet), "
    "or pass --lpips-weights PATH (a file that command wrote)"
)


@dataclass(frozen=True)
class WeightSource:
    """A published weights file: where it is, its byte size and SHA-256."""

    name: str
    url: str
    size: int
    sha256: str


#: torchvision's ImageNet AlexNet (IMAGENET1K_V1); its name carries the SHA-256's first 8 digits.
ALEXNET = WeightSource(
    "alexnet-owt-7be5be79.pth",
    "https://download.pytorch.org/models/alexnet-owt-7be5be79.pth",
    244_408_911,
    "7be5be791159472b1fbf3c69796f7cb30dca7ad8466c2df70058c37116cdee02",
)
#: The LPIPS v0.1 alex heads at the lpips 0.1.4 commit of richzhang/PerceptualSimilarity.
LPIPS_HEADS = WeightSource(
    "alex.pth",
    "https://raw.githubusercontent.com/richzhang/PerceptualSimilarity/"
    "082bb24f84c091ea94de2867d34c4544f68e0963/lpips/weights/v0.1/alex.pth",
    6_009,
    "df73285e35b22355a2df87cdb6b70b343713b667eddbda73e1977e0c860835c0",
)


def cache_path() -> Path:
    """The weights file ``lts weights download`` writes and ``lts eval`` reads by default."""
    return cache_dir() / WEIGHTS_FILE


def torch_hub_alexnet() -> Path:
    """Where torchvision keeps :data:`ALEXNET` (``$TORCH_HOME/hub/checkpoints``)."""
    return Path(torch.hub.get_dir()) / "checkpoints" / ALEXNET.name


def lpips_package_heads() -> Path | None:
    """The heads file the installed lpips package carries (``None`` without the package)."""
    spec = importlib.util.find_spec("lpips")
    if spec is None or spec.origin is None:
        return None
    return Path(spec.origin).parent / "weights" / "v0.1" / LPIPS_HEADS.name


def _state_dict(path: Path) -> dict:
    state = read_torch_file(path)
    if not isinstance(state, dict):
        raise InputError("not a state dict (expected published weights)", path=path)
    return state


def load_lpips(weights: str | Path | None = None) -> LpipsAlex | None:
    """The LPIPS network from ``weights`` or, when ``None``, from the first of the places in the
    module docstring that has it; ``None`` when none has (:data:`HOW_TO_GET` says what to do).
    A file that is there but is not LPIPS alex weights raises :class:`~rig.errors.InputError`."""
    if weights is not None:
        return load_network(weights)
    if cache_path().is_file():
        return load_network(cache_path())
    heads = lpips_package_heads()
    if torch_hub_alexnet().is_file() and heads is not None and heads.is_file():
        state = combined_state(_state_dict(torch_hub_alexnet()), _state_dict(heads))
        return network_from_state(state, f"{torch_hub_alexnet()} + {heads}")
    return None


def sha256_of(path: Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with path.open("rb") as stream:
        for chunk in iter(lambda: stream.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def verify(path: Path, source: WeightSource) -> None:
    """Raise :class:`~rig.errors.InputError` naming ``path`` unless it has ``source``'s size and
    SHA-256."""
    size = path.stat().st_size
    if size != source.size:
        raise InputError(f"{size} bytes, expected {source.size} ({source.url})", path=path, field="size")
    digest = sha256_of(path)
    if digest != source.sha256:
        raise InputError(
            f"SHA-256 {digest} is not the published {source.sha256} ({source.url})",
            path=path,
            field="sha256",
        )


def _verified(path: Path | None, source: WeightSource) -> bool:
    if path is None or not path.is_file():
        return False
    try:
        verify(path, source)
    except InputError:
        return False
    return True


def _download(source: WeightSource, folder: Path, log: Callable[[str], None]) -> Path:
    target = folder / source.name
    log(f"downloading {source.url} ({source.size / 1e6:.1f} MB)")
    try:
        with urllib.request.urlopen(source.url, timeout=60) as response, target.open("wb") as out:
            shutil.copyfileobj(response, out, 1 << 20)
    except (urllib.error.URLError, TimeoutError) as exc:
        reason = getattr(exc, "reason", exc)
        raise OSError(
            f"cannot download {source.url} ({reason}); on a machine without internet, copy "
            f"{WEIGHTS_FILE} from one that has it and pass lts eval --lpips-weights PATH"
        ) from None
    verify(target, source)
    return target


def download_weights(
    out: Path | None = None,
    alexnet: WeightSource = ALEXNET,
    heads: WeightSource = LPIPS_HEADS,
    log: Callable[[str], None] = lambda _: None,
) -> Path:
    """Write the LPIPS weights file to ``out`` (default :func:`cache_path`) from ``alexnet`` and
    ``heads``, each taken from this machine when a copy there has its checksum (the torch hub
    cache, the lpips package) and downloaded and checked otherwise. Returns the path written."""
    out = Path(out) if out is not None else cache_path()
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=out.parent, prefix=".lpips-") as tmp:
        files = []
        for source, local in ((alexnet, torch_hub_alexnet()), (heads, lpips_package_heads())):
            if _verified(local, source):
                log(f"using {local} (SHA-256 checked)")
                files.append(local)
            else:
                files.append(_download(source, Path(tmp), log))
        state = combined_state(_state_dict(files[0]), _state_dict(files[1]))
        network_from_state(state, f"{files[0]} + {files[1]}")
        partial = Path(tmp) / WEIGHTS_FILE
        torch.save(state, partial)
        os.replace(partial, out)
    return out
