"""Build hook (all other metadata is in pyproject.toml): the repository keeps the Jinja2
templates at its top level, templates/; a wheel ships them inside the package, as
derive/templates/, where derive.codegen.render finds them when installed."""
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

TEMPLATES = Path(__file__).resolve().parent / "templates"


class BuildPyWithTemplates(build_py):
    """build_py, plus templates/** copied to derive/templates/** in the build."""

    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False):
            return  # an editable install reads the repository's templates/ in place
        for source in sorted(p for p in TEMPLATES.rglob("*") if p.is_file()):
            target = Path(self.build_lib) / "derive" / "templates" / source.relative_to(TEMPLATES)
            self.mkpath(str(target.parent))
            self.copy_file(str(source), str(target))


setup(cmdclass={"build_py": BuildPyWithTemplates})
