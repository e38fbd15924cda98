from setuptools import find_packages, setup

package_name = 'trainer_console'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    package_data={package_name: ['static/*']},
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Language-attention TAMER maintainers',
    maintainer_email='maintainers@example.org',
    description=('A trainer console in the browser: live frames, feedback and utterances from '
                 'the keyboard, receipts from the learner.'),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'trainer_console = trainer_console.node:main',
            'teach = trainer_console.teach:main',
        ],
    },
)
