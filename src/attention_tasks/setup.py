from setuptools import find_packages, setup

package_name = 'attention_tasks'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    package_data={package_name: ['doorkey/templates/manifest.yaml', 'doorkey/templates/*.png',
                                 'montezuma/data/action_effects.json']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='Language-attention TAMER maintainers',
    maintainer_email='maintainers@example.org',
    description='Task knowledge, one module per task: the world, its state, the expert, '
                "progress and the teacher's sentences.",
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'doorkey_make_templates = attention_tasks.doorkey.make_templates:main',
            'teacher_effects = attention_tasks.montezuma.measure_effects:main',
        ],
    },
)
