"""RequestWatch: how the page's data requests are followed, from DevTools events (no browser here)."""

from stylepong_viz.browser_shot import RequestWatch

DATA = 'http://127.0.0.1:9876/'


def _sent(request_id: str, url: str, timestamp: float) -> dict:
    return {
        'method': 'Network.requestWillBeSent',
        'params': {'requestId': request_id, 'timestamp': timestamp, 'request': {'url': url}},
    }


def _failed(request_id: str, error: str, canceled: bool = False) -> dict:
    return {
        'method': 'Network.loadingFailed',
        'params': {'requestId': request_id, 'errorText': error, 'canceled': canceled},
    }


def test_a_refused_data_request_is_a_failure_once():
    watch = RequestWatch(DATA)
    watch.on_event(_sent('1', DATA + 'ReadMessages', 12.5))
    watch.on_event(_failed('1', 'net::ERR_CONNECTION_REFUSED'))
    assert watch.sent == [(12.5, DATA + 'ReadMessages')]
    assert watch.take_failed() == [DATA + 'ReadMessages: net::ERR_CONNECTION_REFUSED']
    assert watch.take_failed() == []


def test_other_urls_and_cancelled_requests_are_not_failures():
    watch = RequestWatch(DATA)
    watch.on_event(_sent('1', 'https://fonts.googleapis.com/css2', 1.0))  # offline: fails, not the data
    watch.on_event(_failed('1', 'net::ERR_NAME_NOT_RESOLVED'))
    watch.on_event(_sent('2', DATA + 'ReadMessages', 2.0))
    watch.on_event(_failed('2', 'net::ERR_ABORTED', canceled=True))  # the page was opened again
    watch.on_event({'method': 'Network.dataReceived', 'params': {'requestId': '2'}})
    assert watch.sent == [(2.0, DATA + 'ReadMessages')]
    assert watch.take_failed() == []
