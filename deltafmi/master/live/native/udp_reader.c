/* Live UDP inputs read by the master's C loop between its steps (see deltafmi/master/live/native_udp.py).
 *
 * At each communication point of a paced run the C loop calls deltafmi_live_sample, which drains
 * each source's non-blocking socket (at most max_per_poll datagrams) and takes the datagrams it can
 * read as deltafmi/master/live/udp.py's UdpSource would: in arrival order, the newest value of each
 * signal winning, into the unit's values and their bus slots. A datagram it does not take itself is
 * handed to Python with the point: a JSON datagram, one that is malformed (the reason is Python's to
 * say), names a signal the source does not declare, comes from a sender beyond the MAX_SENDERS
 * this reader remembers (Python remembers more), or is older than the newest of its sender (stale
 * or a restart: Python's rules). It stops that source's reading there (the datagram kept in `pending`,
 * the rest left in the socket) and the C loop hands the point back, where Python reads on from
 * exactly there. So does a change of the source's silence (no news for `timeout` wall seconds, or
 * news after it), which Python reports. Datagrams from a host other than the allowed ones are
 * counted as foreign and dropped, as Python does. IPv4 sockets only.
 * Plain C, POSIX sockets, Linux's SO_RXQ_OVFL count where there.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <math.h>
#include <netinet/in.h>
#include <stdint.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <time.h>

enum { FORMAT_DFMI = 0, FORMAT_DOUBLES = 1 };
enum { MAX_SENDERS = 16, MAX_ALLOWED = 8, HEADER = 20, MAX_DATAGRAM = 65507 };

typedef struct {
    uint32_t host;           /* IPv4 address and port, network byte order */
    uint16_t port;
    int known;               /* t and seq hold its newest accepted datagram (else Python's to decide) */
    double t;
    uint32_t seq;
} Sender;

typedef struct {
    int fd;
    int format;
    int float32, big_endian; /* FORMAT_DOUBLES */
    long n;                  /* signals */
    const unsigned char *names; /* FORMAT_DFMI: the declared names' UTF-8 bytes, one after the other */
    const long *name_start, *name_length;
    double *values;          /* the unit's values, by signal */
    double *const *bus;      /* per signal: its bus slot, or NULL */
    unsigned char *fresh;    /* out, per signal: taken at the last point read */
    double *scratch;         /* n: a datagram's values before it is taken whole */
    unsigned char *seen;     /* n */
    double timeout;          /* wall seconds without news before the source is silent; <= 0: never */
    int silent;              /* in: Python reported the source silent */
    double last_news;        /* in/out: CLOCK_MONOTONIC seconds of the last news */
    long max_per_poll;
    long n_allowed;          /* > 0: only these hosts (others: foreign) */
    uint32_t allowed[MAX_ALLOWED];
    Sender senders[MAX_SENDERS];
    long n_senders;
    unsigned char *buffer;   /* MAX_DATAGRAM + 1 bytes */
    long pending;            /* out: size of the datagram in buffer handed to Python, or -1 */
    uint32_t pending_host;
    uint16_t pending_port;
    long received, accepted, foreign; /* out, counted here (Python counts what it reads itself) */
    uint32_t overflow;       /* out: the OS's count of datagrams dropped (SO_RXQ_OVFL) */
    int backlog;             /* out: max_per_poll datagrams read at one point */
} Source;

typedef struct {
    Source *sources;
    long n;
} Readers;

static double monotonic(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double read_le_double(const unsigned char *p)
{
    uint64_t bits = 0;
    for (int i = 7; i >= 0; i--) bits = bits << 8 | p[i];
    double value;
    memcpy(&value, &bits, sizeof value);
    return value;
}

static void take(Source *s, long i, double value)
{
    s->values[i] = value;
    s->fresh[i] = 1;
    if (s->bus[i]) *s->bus[i] = value;
}

/* The sender's entry: a new sender gets one while there is room (its first datagram is then
 * taken here, as Python takes any new sender's), else NULL (Python's) */
static Sender *sender_of(Source *s, uint32_t host, uint16_t port)
{
    for (long i = 0; i < s->n_senders; i++)
        if (s->senders[i].host == host && s->senders[i].port == port) return &s->senders[i];
    if (s->n_senders < MAX_SENDERS) {
        Sender *new_ = &s->senders[s->n_senders++];
        memset(new_, 0, sizeof *new_);
        new_->host = host;
        new_->port = port;
        new_->known = 1;
        new_->t = -INFINITY;
        return new_;
    }
    return NULL;
}

/* 1: taken; 0: Python's (see the file's comment) */
static int take_dfmi(Source *s, const unsigned char *d, long size, uint32_t host, uint16_t port)
{
    if (size < HEADER || d[0] == '{' || memcmp(d, "DFMI", 4) || d[4] != 1 || d[5] != 1) return 0;
    unsigned count = (unsigned)d[6] | (unsigned)d[7] << 8;
    uint32_t seq = (uint32_t)d[8] | (uint32_t)d[9] << 8 | (uint32_t)d[10] << 16 | (uint32_t)d[11] << 24;
    double t = read_le_double(d + 12);
    if (count == 0 || !isfinite(t)) return 0;
    Sender *sender = sender_of(s, host, port);
    if (!sender || !sender->known || t < sender->t) return 0;
    memset(s->seen, 0, (size_t)s->n);
    long offset = HEADER;
    for (unsigned k = 0; k < count; k++) {
        if (offset >= size) return 0;
        long length = d[offset], end = offset + 1 + length;
        if (length == 0 || end + 8 > size) return 0;
        long found = -1;
        for (long i = 0; i < s->n; i++) {
            if (s->name_length[i] == length && !memcmp(s->names + s->name_start[i], d + offset + 1, (size_t)length)) {
                found = i;
                break;
            }
        }
        double value = read_le_double(d + end);
        if (found < 0 || s->seen[found] || !isfinite(value)) return 0;
        s->seen[found] = 1;
        s->scratch[found] = value;
        offset = end + 8;
    }
    if (offset != size) return 0;
    for (long i = 0; i < s->n; i++)
        if (s->seen[i]) take(s, i, s->scratch[i]);
    sender->t = t;
    sender->seq = seq;
    return 1;
}

static int take_doubles(Source *s, const unsigned char *d, long size)
{
    long width = s->float32 ? 4 : 8;
    if (size != width * s->n) return 0;
    for (long i = 0; i < s->n; i++) {
        unsigned char b[8];
        for (long j = 0; j < width; j++) /* to little-endian */
            b[j] = s->big_endian ? d[i * width + width - 1 - j] : d[i * width + j];
        double value;
        if (s->float32) {
            uint32_t bits = (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
            float f;
            memcpy(&f, &bits, sizeof f);
            value = f;
        } else {
            value = read_le_double(b);
        }
        if (!isfinite(value)) return 0;
        s->scratch[i] = value;
    }
    for (long i = 0; i < s->n; i++) take(s, i, s->scratch[i]);
    return 1;
}

/* Reads source s at a point; returns 1 when Python must look at it at this point. */
static int sample_source(Source *s)
{
    int news = 0;
    long read = 0;
    if (s->pending >= 0) return 1; /* Python has not taken the last one yet */
    memset(s->fresh, 0, (size_t)s->n);
    for (; read < s->max_per_poll; read++) {
        struct sockaddr_in from;
        struct iovec iov = {.iov_base = s->buffer, .iov_len = MAX_DATAGRAM + 1};
        union {
            char bytes[CMSG_SPACE(sizeof(uint32_t))];
            struct cmsghdr align;
        } control;
        struct msghdr msg = {.msg_name = &from, .msg_namelen = sizeof from, .msg_iov = &iov, .msg_iovlen = 1,
                             .msg_control = control.bytes, .msg_controllen = sizeof control.bytes};
        ssize_t size = recvmsg(s->fd, &msg, MSG_DONTWAIT);
        if (size < 0) break; /* nothing more, or an ICMP error reported on the socket */
        s->received++;
        for (struct cmsghdr *c = CMSG_FIRSTHDR(&msg); c; c = CMSG_NXTHDR(&msg, c)) {
#ifdef SO_RXQ_OVFL
            if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL && c->cmsg_len >= CMSG_LEN(sizeof(uint32_t)))
                memcpy(&s->overflow, CMSG_DATA(c), sizeof(uint32_t));
#endif
        }
        uint32_t host = from.sin_addr.s_addr;
        if (s->n_allowed > 0) {
            int allowed = 0;
            for (long i = 0; i < s->n_allowed; i++) allowed |= s->allowed[i] == host;
            if (!allowed) {
                s->foreign++;
                continue;
            }
        }
        int taken = s->format == FORMAT_DOUBLES ? take_doubles(s, s->buffer, (long)size)
                                                : take_dfmi(s, s->buffer, (long)size, host, from.sin_port);
        if (!taken) {
            s->pending = (long)size;
            s->pending_host = host;
            s->pending_port = from.sin_port;
            break;
        }
        s->accepted++;
        news = 1;
    }
    if (read == s->max_per_poll) s->backlog = 1;
    double now = monotonic();
    if (news) {
        s->last_news = now;
        if (s->silent) return 1; /* news after a silence: Python says so */
    } else if (s->timeout > 0.0 && !s->silent && now - s->last_news > s->timeout) {
        return 1; /* silent from now: Python says so */
    }
    return s->pending >= 0;
}

/* Every source read at the point at simulation time t; returns 1 when Python must sample them there. */
__attribute__((visibility("default")))
int deltafmi_live_sample(void *context, double t)
{
    (void)t;
    Readers *r = context;
    int python = 0;
    for (long i = 0; i < r->n; i++) python |= sample_source(&r->sources[i]);
    return python;
}
