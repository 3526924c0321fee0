from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'stylepong_fdcc'

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
    description='Forward Dynamics Compliance Control drag teaching.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'drag_teach = stylepong_fdcc.drag_teach_node:main',
            # Recording moved to stylepong_recording; these two keep `ros2 run stylepong_fdcc recorder` and
            # `... recover_bag` working for existing scripts.
            'recorder = stylepong_recording.recorder_node:main',
            'recover_bag = stylepong_recording.recover_bag:main',
        ],
    },
)
