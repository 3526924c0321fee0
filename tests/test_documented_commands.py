"""Every command the documentation shows exists as shown.

The `ros2 run <package> <executable> ...` commands of README.md, docs/DESIGN.md, every package's
README, tools/README.md and demonstrations/README.md must name a console script of that package's
setup.py, and every flag written before `--ros-args` must be one that executable's argument parser
accepts; every `make <target>` must be a target of the Makefile. A renamed flag or executable then
fails here instead of in a reader's shell.

No ROS graph and no node: each executable's parser is captured the moment its `main` asks it to parse,
in one child process (`python3 -m tests.test_documented_commands`), so nothing after the parsing runs.
"""

import argparse
import ast
import importlib
import inspect
import json
import pathlib
import re
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
DOCUMENTS = [
    ROOT / 'README.md',
    ROOT / 'docs/DESIGN.md',
    *sorted((ROOT / 'ros2_ws' / 'src').glob('*/README.md')),
    ROOT / 'tools' / 'README.md',
    ROOT / 'demonstrations' / 'README.md',
]

FENCE = re.compile(r'^```[^\n]*\n(.*?)^```', re.M | re.S)
INLINE = re.compile(r'`([^`]+)`')
SHORT_OR_LONG_FLAG = re.compile(r'^(--[A-Za-z0-9][A-Za-z0-9-]*|-[A-Za-z])$')


def code_snippets(text: str) -> list[str]:
    """The shell lines of fenced blocks (continuations joined) and the inline code spans of a document."""
    snippets = []
    for block in FENCE.findall(text):
        snippets.extend(block.replace('\\\n', ' ').splitlines())
    prose = FENCE.sub('', text)
    # An inline span may be wrapped over two lines of the Markdown source.
    snippets.extend(span.replace('\n', ' ') for span in INLINE.findall(prose))
    return snippets


def shell_part(command: str) -> str:
    """A command up to its comment, its redirection to the background or the next command of the line."""
    return re.split(r'\s#|[&|;]|\$\(', command, maxsplit=1)[0]


def documented_runs() -> list[tuple[str, str, str, tuple[str, ...]]]:
    """(document, package, executable, flags shown before --ros-args) for every `ros2 run` shown."""
    runs = []
    for document in DOCUMENTS:
        for snippet in code_snippets(document.read_text()):
            for match in re.finditer(r'\bros2 run (.*)', snippet):
                words = shell_part(match.group(1)).split()
                if len(words) < 2 or words[0].startswith(('<', '-', '[')):
                    continue  # the generic form `ros2 run <package> <executable>`, or ros2 run's own options
                package, executable, rest = words[0], words[1], words[2:]
                if '--ros-args' in rest:
                    rest = rest[: rest.index('--ros-args')]
                # `[--speedup 2]` shows an optional flag; `--flag=value` is the flag.
                flags = [word.strip('[]').split('=')[0] for word in rest]
                runs.append(
                    (
                        str(document.relative_to(ROOT)),
                        package,
                        executable,
                        tuple(f for f in flags if SHORT_OR_LONG_FLAG.match(f)),
                    )
                )
    return runs


def documented_make_targets() -> list[tuple[str, str]]:
    """(document, target) for every `make <target>` shown as a command (`VAR=value make target` too)."""
    targets = []
    for document in DOCUMENTS:
        for snippet in code_snippets(document.read_text()):
            for match in re.finditer(r'(?:^|[\s;&|(])make\s+((?:[A-Za-z_]+=\S*\s+)*)([A-Za-z][\w-]*)', snippet):
                targets.append((str(document.relative_to(ROOT)), match.group(2)))
    return targets


def console_scripts(package: str) -> dict[str, str]:
    """{executable: 'module:function'} from the console_scripts of a package's setup.py."""
    setup_py = ROOT / 'ros2_ws' / 'src' / package / 'setup.py'
    if not setup_py.is_file():
        return {}
    scripts = {}
    for node in ast.walk(ast.parse(setup_py.read_text())):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            found = re.fullmatch(r'\s*([\w-]+)\s*=\s*([\w.]+:\w+)\s*', node.value)
            if found:
                scripts[found.group(1)] = found.group(2)
    return scripts


class _ParserCaptured(Exception):
    def __init__(self, parser: argparse.ArgumentParser):
        super().__init__(parser.prog)
        self.parser = parser


def parser_flags(parser: argparse.ArgumentParser) -> set[str]:
    """Every option string of a parser and of its subcommands' parsers."""
    flags = set(parser._option_string_actions)
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                flags |= parser_flags(sub)
    return flags


def capture_flags(entry_point: str) -> list[str] | None:
    """The flags of the parser an entry point's main parses with, or None when it parses nothing.

    The parse is stopped as it starts: the executable's work (training, a node) never begins.
    """
    module_name, function_name = entry_point.split(':')
    main = getattr(importlib.import_module(module_name), function_name)
    original = argparse.ArgumentParser.parse_known_args

    def capture(self, *_args, **_kwargs):
        raise _ParserCaptured(self)

    argparse.ArgumentParser.parse_known_args = capture
    saved_argv = sys.argv
    sys.argv = [function_name, '--help']
    try:
        main(['--help']) if inspect.signature(main).parameters else main()
    except _ParserCaptured as captured:
        return sorted(parser_flags(captured.parser))
    except SystemExit:
        return None
    finally:
        argparse.ArgumentParser.parse_known_args = original
        sys.argv = saved_argv
    return None


RUNS = documented_runs()


def test_the_documents_show_commands():
    # A broken extraction would make every other test here pass on nothing.
    assert len(RUNS) > 30
    assert ('README.md', 'stylepong_policy', 'player', ()) in RUNS
    assert {target for _, target in documented_make_targets()} >= {'demo', 'test', 'setup'}


@pytest.mark.parametrize('document, package, executable', sorted({(d, p, e) for d, p, e, _ in RUNS}))
def test_documented_executable_is_a_console_script(document, package, executable):
    scripts = console_scripts(package)
    assert executable in scripts, (
        f'{document} shows `ros2 run {package} {executable}`, but '
        f'ros2_ws/src/{package}/setup.py registers {sorted(scripts)}'
    )


@pytest.fixture(scope='module')
def accepted_flags() -> dict[str, list[str] | None]:
    """{'package executable': flags} for the executables shown with flags, from one child process."""
    wanted = sorted({(p, e) for _, p, e, flags in RUNS if flags and e in console_scripts(p)})
    request = {f'{p} {e}': console_scripts(p)[e] for p, e in wanted}
    result = subprocess.run(
        [sys.executable, '-m', 'tests.test_documented_commands', json.dumps(request)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize('document, package, executable, flags', sorted({r for r in RUNS if r[3]}))
def test_documented_flags_are_accepted(document, package, executable, flags, accepted_flags):
    if executable not in console_scripts(package):
        pytest.skip('not a console script: test_documented_executable_is_a_console_script fails for it')
    accepted = accepted_flags[f'{package} {executable}']
    assert accepted is not None, f'{package} {executable} takes no flags, yet {document} shows {flags}'
    unknown = [flag for flag in flags if flag not in accepted]
    assert not unknown, (
        f'{document}: `ros2 run {package} {executable}` shows {unknown}, which it does not '
        f'accept (it accepts {accepted})'
    )


@pytest.mark.parametrize('document, target', sorted(set(documented_make_targets())))
def test_documented_make_target_exists(document, target):
    makefile = (ROOT / 'Makefile').read_text()
    assert re.search(rf'^{re.escape(target)}\s*:', makefile, re.M), f'{document} shows `make {target}`'


def heading_anchors(document: pathlib.Path) -> set[str]:
    """The anchors GitHub gives a document's headings: lower case, punctuation dropped, spaces to '-'."""
    prose = FENCE.sub('', document.read_text())
    return {
        re.sub(r'[^\w\- ]', '', heading.strip().lower()).replace(' ', '-')
        for heading in re.findall(r'^#+\s+(.*)$', prose, re.M)
    }


LINKED_DOCUMENTS = sorted({*DOCUMENTS, ROOT / 'experiments' / 'README.md', ROOT / 'results' / 'README.md'})


@pytest.mark.parametrize('document', LINKED_DOCUMENTS, ids=lambda d: str(d.relative_to(ROOT)))
def test_links_to_sections_resolve(document):
    # DESIGN's sections are linked from READMEs and named in code comments; a renamed heading must not
    # leave a link pointing at nothing.
    broken = []
    for target, anchor in re.findall(r'\]\(([^)\s#]*)#([^)\s]+)\)', FENCE.sub('', document.read_text())):
        path = (document.parent / target).resolve() if target else document
        if not path.is_file() or anchor not in heading_anchors(path):
            broken.append(f'{target}#{anchor}')
    assert not broken, f'{document.relative_to(ROOT)} links to missing sections: {broken}'


PACKAGES_WITH_CONFIG = sorted(path.parent for path in (ROOT / 'ros2_ws' / 'src').glob('*/config'))


@pytest.mark.parametrize('package', PACKAGES_WITH_CONFIG, ids=lambda p: p.name)
def test_every_config_file_is_named_in_its_readme(package):
    # A parameter file nobody mentions is one nobody finds: each YAML under config/ appears in the package's
    # README by its path inside config/ (`ppo.yaml`, `styles/compact.yaml`).
    readme = (package / 'README.md').read_text()
    unnamed = [
        str(path.relative_to(package / 'config'))
        for path in sorted((package / 'config').rglob('*.yaml'))
        if str(path.relative_to(package / 'config')) not in readme
    ]
    assert not unnamed, f'{package.name}/README.md does not name config/{unnamed}'


def test_a_missing_flag_is_caught():
    # The capture itself must see a parser's flags, or the flag test above would pass on anything.
    flags = capture_flags('stylepong_recording.compress_bag:main')
    assert flags is not None and '--help' in flags and '--no-such-flag' not in flags


if __name__ == '__main__':
    # The child process of accepted_flags: {'package executable': 'module:function'} in, flags out.
    found = {name: capture_flags(entry_point) for name, entry_point in json.loads(sys.argv[1]).items()}
    print(json.dumps(found))
