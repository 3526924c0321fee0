"""Each fact that several programs share is defined in exactly one module and imported everywhere else.

A second definition drifts: the robot side and the simulator, or two scripts, end up disagreeing about a
frame's name, a label's order or an exit code, and nothing fails until the two meet. This test reads every
Python file of the tree with `ast` (no import, no ROS) and fails, naming the file and line, when a
module-level assignment, class or function definition of one of the names below appears outside its home,
or when a module-level constant outside the home spells out one of the shared values themselves. Where the
facts live and why: docs/DESIGN.md, "One source of truth".
"""

from __future__ import annotations

import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
SRC = 'ros2_ws/src/'
ROBOT_CELL = SRC + 'stylepong_description/stylepong_description/robot_cell.py'
ROBOT_MODEL = SRC + 'stylepong_description/stylepong_description/robot_model.py'
SPEC = SRC + 'stylepong_player/stylepong_player/spec.py'
WORLD_SPEC = SRC + 'stylepong_sim/stylepong_sim/world_spec.py'
REFEREE = SRC + 'stylepong_sim/stylepong_sim/referee.py'
EXIT_CODES = SRC + 'stylepong_common/stylepong_common/exit_codes.py'
NODE_SUPPORT = SRC + 'stylepong_common/stylepong_common/node_support.py'

# The rally events: stylepong_msgs/msg/RallyEvent.msg defines them; the referee binds them for Python.
EVENT_CODES = (
    'LAUNCHED',
    'BOUNCE_OWN_SIDE',
    'PADDLE_HIT',
    'BOUNCE_OPPONENT_SIDE',
    'NET',
    'ROBOT_CONTACT',
    'TABLE_CONTACT_BY_ROBOT',
    'OUT',
    'TIMEOUT',
    'RALLY_END',
)

# name -> the one file that may define it.
HOMES = {
    'FRAME_WORLD': ROBOT_CELL,
    'STROKE_LABELS': ROBOT_CELL,
    'JointLimits': ROBOT_MODEL,
    'ToolLoad': ROBOT_MODEL,
    'clip_action': SPEC,
    'decode_action': SPEC,
    'FIRST_EVALUATION_SEED': WORLD_SPEC,
    'EVALUATION_SEEDS': WORLD_SPEC,
    'EVALUATION_BALLS_PER_SEED': WORLD_SPEC,
    'ROS_EVALUATION_BALLS_PER_SEED': WORLD_SPEC,
    'EXIT_STOPPED': EXIT_CODES,
    'EXIT_CONFIG_ERROR': EXIT_CODES,
    'EXIT_INTERRUPTED': EXIT_CODES,
    'WARN_PERIOD_S': NODE_SUPPORT,
}
# Names too common to own outright (ball_contacts has its own NET contact kind): a copy is one of these
# bound to a number.
NUMBER_HOMES = {name: REFEREE for name in EVENT_CODES}
# Names the stroke labels had in their former copies: a module may import the labels under them
# (`from ...robot_cell import STROKE_LABELS as DIRECTIONS`) but never assign them.
FORMER_NAMES = {'SWINGS': ROBOT_CELL, 'DIRECTIONS': ROBOT_CELL, 'LABELS': ROBOT_CELL, 'JointMotionLimits': ROBOT_MODEL}
# Values whose spelling out is a copy whatever the constant is called.
SHARED_VALUES = {
    ('forward', 'leftward', 'rightward'): ('STROKE_LABELS', ROBOT_CELL),
    'world': ('FRAME_WORLD', ROBOT_CELL),
}
# Generated, installed or downloaded trees and run outputs: not the project's source.
SKIPPED_DIRS = {'.git', '.venv', 'build', 'install', 'log', 'runs', '.gpu', '__pycache__', 'node_modules'}


def python_files() -> list[pathlib.Path]:
    """Every Python file of the tree: *.py, and the scripts without a suffix whose first line runs python."""
    found = []
    stack = [ROOT]
    while stack:
        folder = stack.pop()
        for path in folder.iterdir():
            if path.is_dir():
                if path.name not in SKIPPED_DIRS and not path.is_symlink():
                    stack.append(path)
            elif path.suffix == '.py':
                found.append(path)
            elif not path.suffix and path.is_file() and _is_python_script(path):
                found.append(path)
    return sorted(found)


def _is_python_script(path: pathlib.Path) -> bool:
    with path.open('rb') as file:
        first = file.readline(200)
    return first.startswith(b'#!') and b'python' in first


def module_level(tree: ast.Module):
    """The statements that run at import: the module's body and what its top-level if/try blocks hold."""
    stack = list(tree.body)
    while stack:
        node = stack.pop(0)
        if isinstance(node, ast.If):
            stack.extend(node.body + node.orelse)
        elif isinstance(node, ast.Try):
            stack.extend(node.body + node.orelse + node.finalbody + [s for h in node.handlers for s in h.body])
        else:
            yield node


def definitions(tree: ast.Module):
    """(name, line, value or None) of every module-level assignment, class and function."""
    for node in module_level(tree):
        if isinstance(node, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node.name, node.lineno, None
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                elements = target.elts if isinstance(target, (ast.Tuple, ast.List)) else [target]
                for element in elements:
                    if isinstance(element, ast.Name):
                        yield element.id, node.lineno, node.value


def literal(value: ast.expr | None):
    """The value of a literal expression (lists as tuples), or None when it is not a literal."""
    if value is None:
        return None
    try:
        result = ast.literal_eval(value)
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
        return None
    if isinstance(result, list):
        result = tuple(result)
    try:
        hash(result)
    except TypeError:  # a tuple holding a list or a dict: no shared value looks like that
        return None
    return result


def second_definitions(files: list[pathlib.Path], root: pathlib.Path = ROOT) -> list[str]:
    """One line per definition of a shared fact outside its home: 'file:line: what, and where it lives'."""
    problems = []
    for path in files:
        rel = path.relative_to(root).as_posix()
        tree = ast.parse(path.read_text(encoding='utf-8'), filename=rel)
        for name, line, value in definitions(tree):
            home = HOMES.get(name) or FORMER_NAMES.get(name)
            if home is not None and rel != home:
                problems.append(f'{rel}:{line}: defines {name}; its one home is {home}: import it from there')
                continue
            value = literal(value)
            home = NUMBER_HOMES.get(name)
            if home is not None and rel != home and isinstance(value, int):
                problems.append(f'{rel}:{line}: {name} = {value!r} copies a rally event code; import it from {home}')
            elif value in SHARED_VALUES:
                fact, home = SHARED_VALUES[value]
                if rel != home:
                    problems.append(f'{rel}:{line}: {name} spells out {fact} ({value!r}); import {fact} from {home}')
    return problems


def test_every_home_defines_its_facts():
    """The homes named here hold the facts (a moved home must move this table with it)."""
    homes = {**HOMES, **NUMBER_HOMES}
    for home in sorted(set(homes.values())):
        defined = {name for name, _, _ in definitions(ast.parse((ROOT / home).read_text(encoding='utf-8')))}
        missing = sorted(name for name, where in homes.items() if where == home and name not in defined)
        assert not missing, f'{home} no longer defines {missing}'


def test_the_event_codes_are_the_messages():
    """The referee binds each event code to the RallyEvent message's constant, never to a number."""
    tree = ast.parse((ROOT / REFEREE).read_text(encoding='utf-8'))
    bound = {name: value for name, _, value in definitions(tree) if name in EVENT_CODES}
    for name in EVENT_CODES:
        value = bound[name]
        assert isinstance(value, ast.Attribute) and value.attr == name, (
            f'{REFEREE}: {name} must be read from stylepong_msgs RallyEvent.{name}, not written out'
        )


def test_no_shared_fact_is_defined_twice():
    problems = second_definitions(python_files())
    assert not problems, 'a shared fact defined outside its home:\n' + '\n'.join(problems)


@pytest.mark.parametrize(
    'source, expected',
    [
        ("FRAME_WORLD = 'world'\n", 'copy.py:3: defines FRAME_WORLD'),
        ('class JointLimits:\n    pass\n', 'copy.py:3: defines JointLimits'),
        ('if True:\n    EXIT_CONFIG_ERROR = 2\n', 'copy.py:4: defines EXIT_CONFIG_ERROR'),
        ("ORDER = ['forward', 'leftward', 'rightward']\n", 'copy.py:3: ORDER spells out STROKE_LABELS'),
        ("CAMERA_PARENT = 'world'\n", 'copy.py:3: CAMERA_PARENT spells out FRAME_WORLD'),
        ("DIRECTIONS = ('forward', 'leftward', 'rightward')\n", 'copy.py:3: defines DIRECTIONS'),
        ('RALLY_END = 9\n', 'copy.py:3: RALLY_END = 9 copies a rally event code'),
    ],
)
def test_a_copy_is_found_and_named(tmp_path, source, expected):
    """The check itself: a copy in a file of the tree is reported with its file and line."""
    copy = tmp_path / 'copy.py'
    copy.write_text('"""A copy."""\nimport os\n' + source)
    problems = second_definitions([copy], root=tmp_path)
    assert len(problems) == 1 and problems[0].startswith(expected), problems


def test_an_import_is_no_copy(tmp_path):
    copy = tmp_path / 'user.py'
    copy.write_text(
        'from stylepong_description.robot_cell import FRAME_WORLD, STROKE_LABELS as DIRECTIONS\n'
        'NET = "net"\n'
        'def frame():\n    FRAME_WORLD = "world"\n    return FRAME_WORLD\n'
    )
    assert second_definitions([copy], root=tmp_path) == []
