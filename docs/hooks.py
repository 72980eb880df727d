"""MkDocs hook (mkdocs.yml ``hooks:``): serve the committed figures under ``renders/``.

The figures live where the commands write them, outside ``docs/``; this adds every image
under ``renders/`` (less the scratch folders .gitignore names) to the site at the same path, so a page links ``../renders/fig3.png``
and ``mkdocs build --strict`` checks that link like any other.
"""
from __future__ import annotations

from pathlib import Path

from mkdocs.structure.files import File

ROOT = Path(__file__).resolve().parent.parent
IMAGES = (".png", ".gif", ".svg", ".jpg")


def on_files(files, config):
    for path in sorted((ROOT / "renders").rglob("*")):
        parts = path.relative_to(ROOT).parts           # not the checkout's own folders
        scratch = any(part == "tmp" or part.endswith("-quick") for part in parts)
        if path.suffix.lower() in IMAGES and path.is_file() and not scratch:
            rel = "/".join(parts)
            if files.get_file_from_path(rel) is None:
                files.append(File(rel, src_dir=str(ROOT), dest_dir=config["site_dir"],
                                  use_directory_urls=config["use_directory_urls"]))
    return files
