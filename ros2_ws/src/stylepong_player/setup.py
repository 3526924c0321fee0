from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'stylepong_player'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='StylePong developers',
    maintainer_email='dev@stylepong.org',
    description='The trained actor on the robot: the observation/action contract, the exported actor checks, '
    'the ball estimator and the 60 Hz player node, without torch or the simulator.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'player = stylepong_player.player_node:main',
            'ball_estimator = stylepong_player.ball_estimator_node:main',
        ],
    },
)
