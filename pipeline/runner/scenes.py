"""The scenes of a run: meshes from a ``build-meshes`` folder and the fixed protocol scenes.

The catalogue (names, mesh paths, sha256) is fixed when a run starts. Its meshes are copied into
the dataset folder as ``meshes/<sha256><suffix>`` (content-addressed: a mesh used by several runs
or shards is one file) and the dataset stores these relative paths, so a version is
self-contained and can be moved. Workers load scenes from the copies lazily, checking each
mesh's sha256 as they load it (a mesh changed during a run stops the run), and a resumed run
checks that no mesh changed since.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass, replace
from pathlib import Path

from pipeline.config.simulate import ScenesConfig
from pipeline.datasets.versions import MESHES_DIR
from pipeline.errors import RunAborted, UserError
from pipeline.meshes.manifest import load_manifest
from pipeline.protocols.whisking import parse_scene
from pipeline.provenance import file_sha256
from pipeline.scenes.library import mesh_scene
from pipeline.scenes.obstacles import Scene


@dataclass(frozen=True)
class SceneEntry:
    """A scene of the run: ``mesh:NAME`` with its file and hash, or a fixed scene's name."""

    name: str
    path: str = ""
    sha256: str = ""

    @property
    def is_mesh(self) -> bool:
        return bool(self.path)

    def load(self) -> Scene:
        """The scene; a mesh only if its file still has the sha256 the run recorded."""
        if not self.is_mesh:
            return parse_scene(self.name)
        try:
            found = file_sha256(Path(self.path))
        except OSError as exc:
            raise RunAborted(f"mesh {self.path} of scene {self.name} cannot be read ({exc.strerror}); "
                             "the run stopped, its remaining trials are pending") from None
        if found != self.sha256:
            raise RunAborted(f"mesh {self.path} changed during the run (sha256 {found[:12]}…, the run "
                             f"recorded {self.sha256[:12]}…); the run stopped, its remaining trials are "
                             "pending: restore the mesh and --resume, or start a new version")
        return replace(mesh_scene(self.path), name=self.name)      # the copy's file name is its hash

    def in_dataset(self) -> "SceneEntry":
        """This entry as a dataset stores it: its mesh as ``meshes/<sha256><suffix>``."""
        if not self.is_mesh:
            return self
        return replace(self, path=f"{MESHES_DIR}/{self.sha256}{Path(self.path).suffix}")

    def under(self, folder: Path) -> "SceneEntry":
        """A stored entry with its mesh path taken against the dataset ``folder`` (absolute)."""
        return replace(self, path=str(Path(folder).resolve() / self.path)) if self.is_mesh else self



def copy_meshes(scenes: tuple[SceneEntry, ...], folder: Path) -> None:
    """Copy the meshes of ``scenes`` (source paths) into ``folder/meshes/`` under their sha256
    names, unless already there; a copy is written beside and renamed, so it is whole or absent."""
    for entry in scenes:
        if not entry.is_mesh:
            continue
        target = Path(folder) / entry.in_dataset().path
        if target.is_file():
            continue
        target.parent.mkdir(parents=True, exist_ok=True)
        partial = target.with_name(target.name + ".partial")
        shutil.copyfile(entry.path, partial)
        partial.replace(target)


def mesh_files(folder: Path) -> list[Path]:
    """Meshes of a ``build-meshes`` folder: the ok entries of its manifest, else every ``*.obj``."""
    scans = load_manifest(folder)["scans"]
    if scans:
        return sorted(folder / entry["output"]["path"] for entry in scans.values()
                      if entry.get("status") == "ok" and entry.get("output"))
    return sorted(folder.glob("*.obj"))


def _mesh_entry(path: Path) -> SceneEntry:
    if not path.is_file():
        raise UserError(f"mesh not found: {path} (build meshes with `pipeline build-meshes`)")
    return SceneEntry(f"mesh:{path.stem}", str(path.resolve()), file_sha256(path))


def scene_catalogue(config: ScenesConfig) -> tuple[SceneEntry, ...]:
    """The run's scenes in ``include`` order (duplicates dropped); trial i uses entry i mod count."""
    folder = Path(config.folder)
    entries: list[SceneEntry] = []
    for item in config.include:
        if item == "meshes":
            found = mesh_files(folder)
            if not found:
                raise UserError(f"no meshes in {folder}/ (build them with "
                                f"`pipeline build-meshes --out {folder}`)")
            entries += [_mesh_entry(path) for path in found]
        elif item.startswith("mesh:"):
            entries.append(_mesh_entry(folder / f"{item[5:]}.obj"))
        else:
            entries.append(SceneEntry(item))
    return tuple(dict.fromkeys(entries))
