"""The player runs on a robot computer without the training stack: loading its node pulls in neither torch,
matplotlib, the simulator nor the training package (checked in a fresh interpreter, through sys.modules)."""

import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

FORBIDDEN = ('torch', 'matplotlib', 'stylepong_sim', 'stylepong_policy')


def test_importing_the_player_node_loads_no_training_stack():
    probe = (
        'import json, sys; import stylepong_player.player_node; '
        f'print(json.dumps(sorted(m for m in sys.modules if m.split(".")[0] in {FORBIDDEN!r})))'
    )
    result = subprocess.run([sys.executable, '-c', probe], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout.strip().splitlines()[-1]) == []


def test_the_package_depends_on_neither_the_simulator_nor_the_training_package():
    package = ET.parse(Path(__file__).resolve().parent.parent / 'package.xml').getroot()
    depends = {element.text for element in package if element.tag.endswith('depend')}
    assert not depends & {'stylepong_sim', 'stylepong_policy'}, depends
