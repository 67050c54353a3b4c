r"""Sphinx extension for the lagolib book's site: local MathJax, tagged displays, scripts once.

* **MathJax without a network.**  Sphinx loads MathJax from a CDN by default, so the built site
  shows raw TeX wherever the reader (or the browser test) is offline.  When a MathJax 2 folder is
  at hand — ``$LAGOLIB_MATHJAX``, or Debian's ``libjs-mathjax`` at ``/usr/share/javascript/mathjax``
  (with ``fonts-mathjax``) — its script, CommonHTML output and web fonts are copied into
  ``_static/mathjax`` and the pages load them from there.  Without one, the CDN default stays.
* **Tagged equations.**  A chapter numbers an equation as its source does, with ``\tag{13}`` in
  ``$$…$$`` (which Jupyter renders too).  Sphinx wraps every display containing ``\\`` — even
  inside a matrix — in ``\begin{split}``, where ``\tag`` is an error.  Displays with a tag are
  passed to MathJax as written, between ``\[`` and ``\]``.
* **Scripts once.**  Jupyter Book 1 registers sphinx-thebe's inline configuration script twice;
  the second copy re-declares a ``const`` and raises in the browser console.  Identical
  ``<script>`` lines are kept once in every written page.
* **Chapters executed as the tests execute them.**  The build runs every chapter with
  ``lagolib_headless.PassiveClient`` (this folder): IPC sockets, nothing sent to the kernel while
  a cell runs — nbclient's stock client echoes widget output back to the kernel mid-cell, and an
  ``interact`` cell then sometimes idled for the whole cell timeout — and no wait on the kernel
  unchecked for more than a second.  Each chapter's per-cell timeout is its
  ``metadata["execution"]["timeout"]``.
"""

import os
import shutil
from pathlib import Path

from docutils import nodes

DEBIAN_MATHJAX = Path("/usr/share/javascript/mathjax")
CONFIG = "TeX-AMS_CHTML-full"
# what the CommonHTML output needs of a MathJax 2 tree: ~9 MB of the 54 MB Debian installs
SKIP = (
    "unpacked",
    "test",
    "otf",
    "eot",
    "svg",
    "png",
    "SVG",
    "HTML-CSS",
    "NativeMML",
    "PreviewHTML",
    "PlainSource",
    "localization",
)


def mathjax_folder():
    """A MathJax 2 folder to serve locally, or None (then the CDN default is kept)."""
    for folder in (os.environ.get("LAGOLIB_MATHJAX"), DEBIAN_MATHJAX):
        if (
            folder
            and (Path(folder) / "MathJax.js").is_file()
            and (Path(folder) / "config" / f"{CONFIG}.js").is_file()
        ):
            return Path(folder)
    return None


def _use_local_mathjax(app, config):
    folder = mathjax_folder()
    if folder is None:
        return
    config.mathjax_path = f"mathjax/MathJax.js?config={CONFIG}"
    config.mathjax3_config = None
    classes = "math|output_area|tex2jax_process|mathjax_process"
    config.mathjax2_config = {
        "tex2jax": {
            "processClass": classes,
            "ignoreClass": "tex2jax_ignore|mathjax_ignore",
            "inlineMath": [["\\(", "\\)"]],
            "displayMath": [["\\[", "\\]"]],
        },
    }
    app.env_mathjax_folder = folder  # read by _copy_mathjax


def _copy_mathjax(app):
    folder = getattr(app, "env_mathjax_folder", None)
    if folder is None or app.builder.format != "html":
        return
    target = Path(app.outdir) / "_static" / "mathjax"
    if (target / "MathJax.js").is_file():
        return
    shutil.copytree(folder, target, dirs_exist_ok=True, ignore=shutil.ignore_patterns(*SKIP))
    woff = folder / "fonts" / "HTML-CSS" / "TeX" / "woff"  # CommonHTML's web fonts
    shutil.copytree(woff, target / "fonts" / "HTML-CSS" / "TeX" / "woff", dirs_exist_ok=True)


def _tagged_displays_unwrapped(app, doctree):
    for node in doctree.findall(nodes.math_block):
        latex = node.astext()
        if "\\tag{" in latex and not node.get("nowrap"):
            node["nowrap"] = True
            node.children = [nodes.Text(f"\\[{latex}\\]")]


def _scripts_once(app, exc):
    if exc is not None or app.builder.format != "html":
        return
    for page in Path(app.outdir).rglob("*.html"):
        lines = page.read_text(encoding="utf-8").split("\n")
        seen, kept = set(), []
        for line in lines:
            tag = line.strip()
            if tag.startswith("<script") and tag.endswith("</script>"):
                if tag in seen:
                    continue
                seen.add(tag)
            kept.append(line)
        if len(kept) != len(lines):
            page.write_text("\n".join(kept), encoding="utf-8")


def setup(app):
    import lagolib_headless  # beside this file (Sphinx puts _ext on the path)

    lagolib_headless.install()
    app.connect("config-inited", _use_local_mathjax)
    app.connect("builder-inited", _copy_mathjax)
    app.connect("doctree-read", _tagged_displays_unwrapped)
    app.connect("build-finished", _scripts_once)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
