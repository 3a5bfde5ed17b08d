"""MkDocs hook: `experiments/results/RESULTS.md` on the site as it is in the repository.

The site shows it at `assets/results/RESULTS.md` (`docs/assets/results` links to
`experiments/results`), where its figures (beside it) resolve as they do on disk; its
links to the docs pages are written from `experiments/results/` (`../../docs/PAGE.md`), so
here they lose the `docs/`. Likewise the changelog page is the repository's
`CHANGELOG.md`, whose links to the docs are written from the root (`docs/PAGE.md`): the
hook puts its text in place of the page's snippet line (the snippet would be included only
after this hook, and after MkDocs checks the links) and takes the `docs/` off.
"""

from pathlib import Path

RESULTS = "assets/results/RESULTS.md"
CHANGELOG = "changelog.md"
CHANGELOG_SNIPPET = '--8<-- "CHANGELOG.md"'


def on_page_markdown(markdown, page, config=None, **kwargs):
    if page.file.src_uri == RESULTS:
        return markdown.replace("](../../docs/", "](../../")
    if page.file.src_uri == CHANGELOG:
        changelog = (Path(config["config_file_path"]).parent / "CHANGELOG.md").read_text()
        return markdown.replace(CHANGELOG_SNIPPET, changelog).replace("](docs/", "](")
    return markdown
