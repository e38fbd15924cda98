from glob import glob

from setuptools import find_packages, setup

package_name = 'attention_bringup'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    # The YAML files travel with the Python package (the launcher finds them next to its code)
    # and are also installed to share/ for ros2 launch.
    package_data={package_name: ['config/*.yaml', 'config/conditions/*.yaml',
                                 'config/tasks/*.yaml', 'config/experiments/*.yaml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
        ('share/' + package_name + '/config', glob(package_name + '/config/*.yaml')),
        ('share/' + package_name + '/config/conditions',
         glob(package_name + '/config/conditions/*.yaml')),
        ('share/' + package_name + '/config/tasks', glob(package_name + '/config/tasks/*.yaml')),
        ('share/' + package_name + '/config/experiments',
         glob(package_name + '/config/experiments/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Language-attention TAMER maintainers',
    maintainer_email='maintainers@example.org',
    description=('Launcher, parameter files, launch file and study runner for the '
                 'language-attention TAMER graph.'),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'attention_train = attention_bringup.launcher:main',
            'attention_experiment = attention_bringup.experiment.cli:main',
            'attention_study = attention_bringup.study.cli:main',
            'attention_teaching = attention_bringup.teaching.cli:main',
            'attention_study_minigrid = attention_bringup.minigrid_study.cli:main',
            'attention_replay = attention_bringup.replay.cli:main',
        ],
    },
)
