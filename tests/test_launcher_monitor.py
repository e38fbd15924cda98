"""
The launcher's monitor node with real rclpy.

Its spinning survives a failing callback, and its image subscriptions come and go on the
executor's own thread as the gallery asks.
"""

import io
import os
import threading

from attention_bringup.gallery import GalleryCollector
from attention_bringup.monitor import GraphMonitor, spin_until_shutdown
from attention_bringup.progress import ProgressTracker
from attention_common import topics
from harness import wait_until
import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node


@pytest.fixture
def spinning():
    """Yield (context, executor, err) with spin_until_shutdown running on a thread."""
    context = Context()
    rclpy.init(context=context)
    executor = SingleThreadedExecutor(context=context)
    err = io.StringIO()
    result = {}
    thread = threading.Thread(
        target=lambda: result.setdefault('errors', spin_until_shutdown(executor, context, err)),
        daemon=True)
    yield context, executor, err, thread, result
    executor.shutdown(timeout_sec=2.0)
    rclpy.try_shutdown(context=context)
    thread.join(timeout=5.0)


def _subscribed_topics(node: Node) -> set:
    return {subscription.topic_name.lstrip('/') for subscription in node.subscriptions}


@pytest.mark.topics
def test_a_failing_callback_is_reported_and_spinning_goes_on(spinning):
    context, executor, err, thread, result = spinning
    node = Node('failing_callback', context=context)
    calls = []

    def tick():
        calls.append(1)
        if len(calls) == 1:
            raise RuntimeError('first tick fails')

    node.create_timer(0.02, tick)
    executor.add_node(node)
    thread.start()
    assert wait_until(lambda: len(calls) >= 5, timeout=10.0), 'the timer stopped after the error'
    executor.shutdown(timeout_sec=2.0)
    rclpy.try_shutdown(context=context)
    thread.join(timeout=5.0)
    assert not thread.is_alive()
    assert result['errors'] == 1
    assert 'RuntimeError: first tick fails' in err.getvalue()
    node.destroy_node()


@pytest.mark.topics
def test_image_subscriptions_follow_the_gallery_on_the_executor_thread(spinning):
    context, executor, err, thread, _ = spinning
    gallery = GalleryCollector(capacity=2, patience=3)
    monitor = GraphMonitor(ProgressTracker(position_of=lambda x, y: -1), gallery,
                           context=context)
    executor.add_node(monitor)
    thread.start()
    gallery_images = {topics.OBSERVATION, topics.SALIENCY_MASK}
    assert topics.SALIENCY not in _subscribed_topics(monitor)
    monitor.watch_images()  # saliency images are counted from then on
    assert wait_until(lambda: topics.SALIENCY in _subscribed_topics(monitor), timeout=5.0)
    assert not gallery_images & _subscribed_topics(monitor)

    with monitor.lock:
        gallery.request()
    assert wait_until(lambda: gallery_images <= _subscribed_topics(monitor), timeout=5.0)
    with monitor.lock:  # patience runs out: the frame alone is taken, the wait ends
        for stamp in range(5):
            gallery.on_image('observation', stamp, b'frame')
    assert len(gallery.samples) == 1
    assert wait_until(lambda: not gallery_images & _subscribed_topics(monitor), timeout=5.0)
    assert topics.SALIENCY in _subscribed_topics(monitor)
    assert err.getvalue() == ''
    monitor.destroy_node()


@pytest.mark.topics
def test_the_spinning_thread_ends_at_stop_before_the_executor_is_shut_down():
    """
    Driver.__exit__ ends the spinning thread before it shuts the executor down.

    Shut down under a spinning thread, rclpy raised 'Attempt to remove nonexistent callback'
    and the process aborted after a finished run.
    """
    from attention_bringup.driver import Driver
    ticks = []

    def make_node(context):
        node = Node('driver_probe', context=context)
        node.create_timer(0.01, lambda: ticks.append(1))
        return node

    for _ in range(5):  # each a context, executor and node of its own, left in order
        with Driver(int(os.environ['ROS_DOMAIN_ID']), make_node, io.StringIO()) as driver:
            assert wait_until(lambda: len(ticks) >= 3, timeout=10.0)
            spinner = driver._spinner
            driver.exit_code = 0
        assert not spinner.is_alive()
        ticks.clear()
    # spin_until_shutdown itself returns at stop while the context is still up.
    context = Context()
    rclpy.init(context=context)
    executor = SingleThreadedExecutor(context=context)
    stop = threading.Event()
    thread = threading.Thread(target=spin_until_shutdown,
                              args=(executor, context, io.StringIO(), stop), daemon=True)
    thread.start()
    stop.set()
    thread.join(timeout=2.0)
    assert not thread.is_alive() and context.ok()
    executor.shutdown(timeout_sec=2.0)
    rclpy.try_shutdown(context=context)
