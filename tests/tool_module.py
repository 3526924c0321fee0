"""A script of tools/ loaded as a module, so that tests call its functions without a subprocess."""
import importlib.util
import pathlib
from types import ModuleType

TOOLS = pathlib.Path(__file__).resolve().parent.parent / 'tools'


def load_tool(name: str) -> ModuleType:
    """tools/<name>.py as a module."""
    spec = importlib.util.spec_from_file_location(name, TOOLS / f'{name}.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
