"""The rendered HTML book, built with Jupyter Book 1 and read in a real browser (headless Chromium).

``jupyter-book build book/`` runs once per session into a temporary folder, executing every
chapter (``execute_notebooks: force``).  A local HTTP server serves the site, and Debian's
``chromium`` — driven by Playwright with ``executable_path``, never a downloaded browser — opens
every page of the table of contents and checks what a reader sees:

* the page loads without console errors, failed requests or script exceptions;
* MathJax typeset every math element without an error, and no raw ``$$``/``$…$`` is left in the
  text;
* every image is present and decoded (``naturalWidth > 0``), at least as many as the chapter
  promises (``metadata["lagolib"]["figures"]``);
* every solution (code cell tagged ``solution``, and its "Solution and discussion") is folded, and
  opens on a click;
* every link of the equation index resolves: its page exists and has the anchor.

A screenshot of chapter 6 is saved to ``book/_build/screenshots/06_lago.png`` (or
``$LAGOLIB_ARTIFACTS``).  The pages need MathJax 2 on this machine (Debian's ``libjs-mathjax
fonts-mathjax``, or ``$LAGOLIB_MATHJAX``), which the site then serves itself: without it the site
would load MathJax from a CDN, which an offline machine cannot reach.  Without Chromium, local
MathJax or Jupyter Book the tests skip, saying which is missing — unless
``LAGOLIB_REQUIRE_BROWSER`` is set (to anything but ``0``; ``.ci/run`` sets it), which turns the
skip into a failure saying what to install.
"""

import functools
import http.server
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
import threading
from pathlib import Path
from urllib.parse import urljoin, urlparse

import pytest

ROOT = Path(__file__).resolve().parent.parent
BOOK = ROOT / "book"
CHROMIUM = os.environ.get("LAGOLIB_CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
BUILD_TIMEOUT = 1500  # seconds; a hang guard only
THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")

pytestmark = pytest.mark.site
# what MathJax makes of a formula it cannot typeset: MathJax 2 shows the TeX source in a box
# (.mjx-noError) over an <merror> in its MathML; MathJax 3 an <mjx-merror> element
MATH_ERRORS = ", ".join(
    f"main {s}"
    for s in ('[data-mathml*="<merror"]', ".mjx-noError", ".mjx-merror", "mjx-merror", ".noError")
)


def _required():
    """True when ``LAGOLIB_REQUIRE_BROWSER`` is set (to anything but empty or ``0``)."""
    return os.environ.get("LAGOLIB_REQUIRE_BROWSER", "").strip() not in ("", "0")


def _unavailable(why, install):
    """Skip for ``why`` — or fail, saying to ``install`` it, when the browser test is required."""
    if _required():
        value = os.environ["LAGOLIB_REQUIRE_BROWSER"]
        pytest.fail(
            f"{why}; install {install} (LAGOLIB_REQUIRE_BROWSER={value}: the site test must run "
            "here)",
            pytrace=False,
        )
    pytest.skip(f"{why} (install {install})")


def _site_extension():
    """The book's Sphinx extension (``book/_ext/lagolib_site.py``), which finds local MathJax."""
    try:
        import docutils  # noqa: F401  (the extension's one import; Jupyter Book brings it)
    except ImportError:
        _unavailable("Jupyter Book 1 is not installed", "the test tools: pip install -e '.[test]'")
    spec = importlib.util.spec_from_file_location("lagolib_site", BOOK / "_ext" / "lagolib_site.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def local_mathjax():
    """The MathJax the site serves itself; skips (or fails) when there is none.

    A site built elsewhere (``LAGOLIB_SITE``) brings its own, in ``_static/mathjax``.
    """
    prebuilt = os.environ.get("LAGOLIB_SITE")
    if prebuilt:
        if not (Path(prebuilt) / "index.html").is_file():
            pytest.fail(f"LAGOLIB_SITE={prebuilt} is not a built site (no index.html)")
        folder = Path(prebuilt) / "_static" / "mathjax"
        if (folder / "MathJax.js").is_file():
            return folder
        _unavailable(
            f"the prebuilt site LAGOLIB_SITE={prebuilt} has no local MathJax "
            "(_static/mathjax/MathJax.js): it would load MathJax from a CDN",
            "libjs-mathjax fonts-mathjax (Debian) and build the site again",
        )
    extension = _site_extension()
    folder = extension.mathjax_folder()
    if folder is None:
        _unavailable(
            f"MathJax 2 is not installed here (no {extension.DEBIAN_MATHJAX}/MathJax.js, "
            "LAGOLIB_MATHJAX unset): the site would load MathJax from a CDN, which the browser "
            "test cannot count on",
            "libjs-mathjax fonts-mathjax (Debian: apt install libjs-mathjax fonts-mathjax), or "
            "set LAGOLIB_MATHJAX to a MathJax 2 folder",
        )
    return folder


def _toc_pages():
    """The files of book/_toc.yml, in order (root first)."""
    text = (BOOK / "_toc.yml").read_text(encoding="utf-8")
    root = re.search(r"^root:\s*(\S+)", text, re.M).group(1)
    return [root] + re.findall(r"-\s*file:\s*(\S+)", text)


PAGES = _toc_pages()
CHAPTERS = [p for p in PAGES if (BOOK / f"{p}.ipynb").exists()]


def _notebook(page):
    return json.loads((BOOK / f"{page}.ipynb").read_text(encoding="utf-8"))


def _n_solutions(page):
    return sum(
        "solution" in c.get("metadata", {}).get("tags", []) for c in _notebook(page)["cells"]
    )


@pytest.fixture(scope="session")
def site(tmp_path_factory):
    """Build the book once; return ``(html folder, build log)``.

    ``LAGOLIB_SITE`` naming an already built ``_build/html`` folder skips the build (for working on
    these tests; the build log is then empty).
    """
    prebuilt = os.environ.get("LAGOLIB_SITE")
    if prebuilt:
        return Path(prebuilt), ""
    jb = Path(sys.executable).with_name("jupyter-book")
    if not jb.exists():
        _unavailable("Jupyter Book 1 is not installed", "the test tools: pip install -e '.[test]'")
    out = tmp_path_factory.mktemp("site")
    env = dict(os.environ)
    env.pop("MPLBACKEND", None)  # the chapters draw inline, as in book/conftest.py
    env.update({k: "1" for k in THREAD_VARS})
    proc = subprocess.run(
        [str(jb), "build", str(BOOK), "--path-output", str(out), "--keep-going"],
        capture_output=True,
        text=True,
        env=env,
        timeout=BUILD_TIMEOUT,
        cwd=ROOT,
    )
    log = proc.stdout + proc.stderr
    html = out / "_build" / "html"
    if proc.returncode != 0 or not (html / "index.html").exists():
        pytest.fail(f"jupyter-book build failed ({proc.returncode}):\n{log[-6000:]}")
    return html, log


@pytest.fixture(scope="session")
def server(site):
    html, _ = site

    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args):
            pass

    handler = functools.partial(Quiet, directory=str(html))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}/"
    httpd.shutdown()


@pytest.fixture(scope="session")
def browser():
    if not Path(CHROMIUM).exists():
        _unavailable(f"Chromium not found at {CHROMIUM}", "chromium (Debian: apt install chromium)")
    local_mathjax()  # before the site is built: without it no page would pass
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        _unavailable("playwright is not installed", "the test tools: pip install -e '.[test]'")
    with sync_playwright() as p:
        b = p.chromium.launch(
            executable_path=CHROMIUM, args=["--no-sandbox", "--disable-gpu"], headless=True
        )
        yield b
        b.close()


class Page:
    """A page opened in the browser, with everything that went wrong while loading it."""

    def __init__(self, browser, url):
        self.page = browser.new_page(viewport={"width": 1280, "height": 1000})
        self.problems = []
        self.page.on(
            "console",
            lambda m: (
                self.problems.append(f"console {m.type}: {m.text}") if m.type == "error" else None
            ),
        )
        self.page.on("pageerror", lambda e: self.problems.append(f"exception: {e}"))
        self.page.on("requestfailed", lambda r: self.problems.append(f"request failed: {r.url}"))
        response = self.page.goto(url, wait_until="load")
        self.status = response.status if response else None

    def wait_for_math(self):
        """Wait until every math element holds MathJax's rendering (MathJax 2 or 3).

        Returns the number of math elements.
        """
        self.page.wait_for_function(
            """() => {
                const math = [...document.querySelectorAll('main .math')];
                const done = el => el.querySelector('.MathJax_CHTML, .MathJax, mjx-container');
                // MathJax 2 lays tags and spacing out again once its web fonts are in
                const hub = window.MathJax && window.MathJax.Hub;
                const idle = !hub || (hub.queue.pending === 0 && !hub.queue.running);
                return math.every(done) && idle && document.fonts.status === 'loaded';
            }""",
            timeout=60_000,
        )
        return self.page.locator("main .math").count()

    def close(self):
        self.page.close()


def _text_outside_code(page):
    return page.evaluate(
        """() => {
            const main = document.querySelector('main').cloneNode(true);
            main.querySelectorAll('pre, code, script, .MathJax_Preview, .math').forEach(
                e => e.remove());
            return main.innerText;
        }"""
    )


class _Extension:
    """Stands in for book/_ext/lagolib_site.py: MathJax at ``folder`` (or nowhere)."""

    DEBIAN_MATHJAX = Path("/usr/share/javascript/mathjax")

    def __init__(self, folder):
        self.folder = folder

    def mathjax_folder(self):
        return self.folder


@pytest.mark.parametrize("require", ["", "0", "1", "yes"])
def test_without_local_mathjax_the_browser_tests_skip_or_fail(monkeypatch, tmp_path, require):
    """No browser needed: Chromium without MathJax skips with the reason, or fails if required."""
    monkeypatch.setattr(sys.modules[__name__], "_site_extension", lambda: _Extension(None))
    monkeypatch.delenv("LAGOLIB_SITE", raising=False)
    monkeypatch.setenv("LAGOLIB_REQUIRE_BROWSER", require)
    if require in ("", "0"):
        with pytest.raises(pytest.skip.Exception, match="MathJax 2 is not installed here") as e:
            local_mathjax()
        assert "from a CDN" in str(e.value) and "libjs-mathjax fonts-mathjax" in str(e.value)
    else:
        with pytest.raises(pytest.fail.Exception, match="MathJax 2 is not installed here") as e:
            local_mathjax()
        assert "install libjs-mathjax fonts-mathjax" in str(e.value)
        assert f"LAGOLIB_REQUIRE_BROWSER={require}: the site test must run here" in str(e.value)
    # with MathJax, or a prebuilt site that serves its own, nothing skips
    monkeypatch.setattr(sys.modules[__name__], "_site_extension", lambda: _Extension(tmp_path))
    assert local_mathjax() == tmp_path
    (tmp_path / "_static" / "mathjax").mkdir(parents=True)
    (tmp_path / "_static" / "mathjax" / "MathJax.js").write_text("")
    (tmp_path / "index.html").write_text("")
    monkeypatch.setattr(sys.modules[__name__], "_site_extension", lambda: _Extension(None))
    monkeypatch.setenv("LAGOLIB_SITE", str(tmp_path))
    assert local_mathjax() == tmp_path / "_static" / "mathjax"


def test_the_real_extension_finds_mathjax_where_the_site_build_does(monkeypatch, tmp_path):
    """The check asks the site's own extension: LAGOLIB_MATHJAX first, else Debian's folder."""
    pytest.importorskip("docutils")
    extension = _site_extension()
    (tmp_path / "config").mkdir()
    (tmp_path / "MathJax.js").write_text("")
    (tmp_path / "config" / f"{extension.CONFIG}.js").write_text("")
    monkeypatch.delenv("LAGOLIB_SITE", raising=False)
    monkeypatch.setenv("LAGOLIB_MATHJAX", str(tmp_path))
    assert local_mathjax() == tmp_path


def test_site_builds_without_warnings(site):
    _, log = site
    warnings = [
        line
        for line in log.splitlines()
        if "WARNING" in line and "[IPKernelApp]" not in line and "TCP without" not in line
    ]
    assert not warnings, "the build warned:\n" + "\n".join(warnings[:30])


@pytest.mark.parametrize("page", PAGES)
def test_page_reads_in_a_browser(page, browser, server):
    p = Page(browser, urljoin(server, f"{page}.html"))
    try:
        assert p.status == 200, f"{page}.html: HTTP {p.status}"
        n_math = p.wait_for_math()
        if page in CHAPTERS:
            assert n_math > 0, f"{page}: no typeset math on the page"
        errors = p.page.locator(MATH_ERRORS)
        assert errors.count() == 0, (
            f"{page}: MathJax could not typeset {errors.count()} formulas, e.g. "
            f"{errors.first.inner_text()[:200]!r}"
        )
        text = _text_outside_code(p.page)
        assert "$$" not in text, f"{page}: raw $$ left in the text"
        raw = re.findall(r"\$[^$\s][^$\n]{0,40}\$", text)
        assert not raw, f"{page}: untypeset inline math {raw[:3]}"
        images = p.page.eval_on_selector_all(
            "main img", "els => els.map(e => [e.currentSrc, e.complete, e.naturalWidth])"
        )
        broken = [src for src, complete, width in images if not complete or width == 0]
        assert not broken, f"{page}: images not decoded: {broken}"
        if page in CHAPTERS:
            promised = _notebook(page)["metadata"]["lagolib"]["figures"]
            assert len(images) >= promised, f"{page}: {len(images)} images, promises {promised}"
        assert not p.problems, f"{page}: " + "\n".join(p.problems)
    finally:
        p.close()


@pytest.mark.parametrize("page", [c for c in CHAPTERS if _n_solutions(c)])
def test_solutions_are_folded_and_open_on_click(page, browser, server):
    p = Page(browser, urljoin(server, f"{page}.html"))
    try:
        code = p.page.locator("main div.cell.tag_solution details")
        discussion = p.page.locator("main details:not(div.cell details)")
        n_code, n_disc = code.count(), discussion.count()
        assert n_code + n_disc == _n_solutions(page), (
            f"{page}: {n_code} folded solution cells and {n_disc} folded discussions, "
            f"{_n_solutions(page)} cells tagged solution"
        )
        for folds in (code, discussion):
            for k in range(folds.count()):
                d = folds.nth(k)
                assert d.get_attribute("open") is None, f"{page}: solution {k} is not folded"
                d.locator("summary").first.click()
                assert d.get_attribute("open") is not None, f"{page}: solution {k} did not open"
                inner = d.evaluate("e => e.innerText.length")
                assert inner > len(d.locator("summary").first.inner_text()), (
                    f"{page}: solution {k} opened empty"
                )
        assert not p.problems, f"{page}: " + "\n".join(p.problems)
    finally:
        p.close()


def test_equation_index_links_resolve(browser, server):
    p = Page(browser, urljoin(server, "equation_index.html"))
    try:
        hrefs = p.page.eval_on_selector_all("main article a[href]", "els => els.map(e => e.href)")
        this = urljoin(server, "equation_index.html")
        local = sorted(
            {h for h in hrefs if h.startswith(server) and h.split("#")[0] != this}
            - {urljoin(server, "_sources/equation_index.md")}
        )
        written = set(
            re.findall(
                r"\]\((\d\d_\w+\.ipynb(?:#[^)]*)?)\)", (BOOK / "equation_index.md").read_text()
            )
        )
        assert len(local) == len(written) > 0, (
            f"the equation index page has {len(local)} local links; its source has {len(written)}"
        )
        targets = {}
        for href in local:
            url = urlparse(href)
            targets.setdefault(url.path, set()).add(url.fragment)
        for path, anchors in targets.items():
            q = Page(browser, urljoin(server, path))
            try:
                assert q.status == 200, f"{path}: HTTP {q.status}"
                missing = [
                    a
                    for a in anchors
                    if a and not q.page.evaluate("a => !!document.getElementById(a)", a)
                ]
                assert not missing, f"{path}: anchors {missing} not found"
            finally:
                q.close()
    finally:
        p.close()


def test_screenshot_of_chapter_6(browser, server):
    folder = Path(os.environ.get("LAGOLIB_ARTIFACTS") or BOOK / "_build" / "screenshots")
    folder.mkdir(parents=True, exist_ok=True)
    p = Page(browser, urljoin(server, "06_lago.html"))
    try:
        p.wait_for_math()
        # a folded solution is on the page; the screenshot starts from the top, nothing focused
        assert p.page.locator("main div.cell.tag_solution details").count() > 0
        p.page.evaluate("() => { window.scrollTo(0, 0); document.activeElement?.blur(); }")
        shot = folder / "06_lago.png"
        p.page.screenshot(path=str(shot), full_page=True)
        assert shot.stat().st_size > 100_000, f"{shot}: {shot.stat().st_size} bytes"
    finally:
        p.close()
