from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'stylepong_sim'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
        ('share/' + PACKAGE + '/config/styles', glob('config/styles/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='StylePong developers',
    maintainer_email='dev@stylepong.org',
    description=(
        'MuJoCo UR5 table-tennis cell standing in for the hardware, world spec, referee, virtual teacher, '
        'batched training world.'
    ),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'ur5_sim = stylepong_sim.nodes.ur5_sim_node:main',
            'ur5_bullet = stylepong_sim.nodes.ur5_sim_node:main_bullet',
            'virtual_teacher = stylepong_sim.nodes.virtual_teacher_node:main',
            'rally_eval = stylepong_sim.nodes.rally_eval:main',
            'cell_calibration = stylepong_sim.nodes.calibration:main',
            'robot_state_publisher = stylepong_sim.nodes.robot_state_publisher_node:main',
        ],
    },
)
