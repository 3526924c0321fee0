from glob import glob
from os.path import isfile

from setuptools import find_packages, setup

PACKAGE = 'stylepong_policy'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
        ('share/' + PACKAGE + '/models', [f for f in glob('models/*') if isfile(f)]),
        ('share/' + PACKAGE + '/models/skills', glob('models/skills/*.pt')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='StylePong developers',
    maintainer_email='dev@stylepong.org',
    description='Training bridge (bags to reference motions), PPO + AMP training, evaluation and the paper figures.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'build_dataset = stylepong_policy.build_dataset:main',
            'train = stylepong_policy.train:main',
            'evaluate = stylepong_policy.evaluate:main',
            'select_checkpoint = stylepong_policy.select_checkpoint:main',
            'average_checkpoints = stylepong_policy.average_checkpoints:main',
            'paper_tables = stylepong_policy.paper_tables:main',
            'style_confusion = stylepong_policy.style_confusion:main',
            'learn_style = stylepong_policy.learn_style:main',
            # The user's pipeline ends in this package (learn_style, then play the actor), so the
            # player is offered under its name too; the one implementation stays in
            # stylepong_player, which the robot computer installs without torch.
            'player = stylepong_player.player_node:main',
        ],
    },
)
