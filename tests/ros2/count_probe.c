/* An independent subscriber to every topic of a running city, with Cyclone DDS's C API only (no
 * code and no type of the project): it finds the topics in the builtin DCPSPublication topic,
 * gets each one's type from its writers by DDS type discovery (dds_create_topic_descriptor on the
 * endpoint's type information), and reads every sample raw (dds_takecdr, nothing decoded) with a
 * keep-all reader of the writers' reliability. It notes each sample's source timestamp, so that a
 * recording can be compared with it over the same window of source time
 * (tests/ros2/record_city.py), and keeps the bytes of the samples of the topics named by
 * --payloads (as dds_takecdr gives them: encapsulation header and payload), so that what another
 * program forwarded can be compared byte for byte (tests/ros2/live_city.py).
 *
 * Usage: count_probe PARTITION SECONDS OUT [--cameras] [--only DDS_TOPIC]...
 *                    [--payloads DDS_TOPIC]... [--watch-readers] [--list-topics]
 * Listens SECONDS (or until SIGINT or SIGTERM), then writes OUT: one JSON line per topic,
 *   {"topic": DDS name, "type": DDS type name, "reliable": bool, "since": ns, "lost": n,
 *    "stamps": [source time ns, ...]}
 * ("since": when its reader was made; "lost": the samples DDS reported lost to it; with
 * --payloads, the topic's line also has "payloads": [hex of each sample, ...] in the order of
 * "stamps"), and prints a
 * summary line per topic on stdout. Prints "count_probe: reading N topics" once it reads some and
 * no new one has appeared for a second. Camera topics (sensor_msgs Image) only with --cameras; with
 * --only, those topics alone (a subscriber on a slow link that reads what it needs). With
 * --watch-readers it also prints, as DCPSSubscription reports them, every reader of another
 * participant that appears or goes: "count_probe: reader+ PARTICIPANT TOPIC" and
 * "count_probe: reader- PARTICIPANT TOPIC" (PARTICIPANT: the 32 hex digits of its GUID). With
 * --list-topics it prints "count_probe: topic DDS_TOPIC TYPE" for each topic of the partition
 * the first time a writer of it (of another participant) is seen, read or not. Exit
 * status 1 when a topic's type is not among the compiled ones. */
#include <dds/dds.h>
#include <dds/ddsi/ddsi_serdata.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_TOPICS 512
#define BATCH 64

struct topic {
  char* name;
  char* type;
  int reliable;
  dds_time_t since;
  dds_entity_t reader;
  int64_t* stamps;
  size_t n, cap;
  int keep_payloads;
  char** payloads; /* hex, one per stamp, when keep_payloads */
};

/* A reader DCPSSubscription announced: its instance, to name it when it goes. */
struct seen_reader {
  dds_instance_handle_t instance;
  char participant[33];
  char* topic;
};

/* The descriptors record_city.py compiled in, NULL-terminated. */
extern const dds_topic_descriptor_t* const probe_types[];

static const dds_topic_descriptor_t* descriptor_of(const char* type_name) {
  for (size_t i = 0; probe_types[i] != NULL; i++) {
    if (strcmp(probe_types[i]->m_typename, type_name) == 0) return probe_types[i];
  }
  return NULL;
}

static struct topic topics[MAX_TOPICS];
static size_t ntopics = 0;
static int failures = 0;
static const char* only[64];
static int nonly = 0;
static const char* payload_topics[64];
static int npayload_topics = 0;
static struct seen_reader* readers_seen = NULL;
static size_t nreaders_seen = 0, readers_cap = 0;
static char* listed[MAX_TOPICS];
static size_t nlisted = 0;

/* --list-topics: names a topic with writers the first time one is seen. */
static void list_topic(const dds_builtintopic_endpoint_t* w) {
  for (size_t i = 0; i < nlisted; i++) {
    if (strcmp(listed[i], w->topic_name) == 0) return;
  }
  if (nlisted == MAX_TOPICS) return;
  listed[nlisted++] = strdup(w->topic_name);
  printf("count_probe: topic %s %s\n", w->topic_name, w->type_name);
  fflush(stdout);
}
static volatile sig_atomic_t stop = 0;

static void on_signal(int sig) {
  (void)sig;
  stop = 1;
}

static struct topic* find(const char* name) {
  for (size_t i = 0; i < ntopics; i++) {
    if (strcmp(topics[i].name, name) == 0) return &topics[i];
  }
  return NULL;
}

static void guid_hex(const dds_guid_t* g, char out[33]) {
  for (int i = 0; i < 16; i++) sprintf(out + 2 * i, "%02x", g->v[i]);
}

/* --watch-readers: prints the readers of other participants as they appear and go. */
static void watch_readers(dds_entity_t subscriptions, const dds_guid_t* me) {
  for (;;) {
    void* samples[BATCH] = {0};
    dds_sample_info_t infos[BATCH];
    const dds_return_t n = dds_take(subscriptions, samples, infos, BATCH, BATCH);
    for (dds_return_t i = 0; i < n; i++) {
      const dds_builtintopic_endpoint_t* r = samples[i];
      if (infos[i].instance_state != DDS_IST_ALIVE) {
        for (size_t k = 0; k < nreaders_seen; k++) {
          if (readers_seen[k].instance != infos[i].instance_handle) continue;
          printf("count_probe: reader- %s %s\n", readers_seen[k].participant, readers_seen[k].topic);
          free(readers_seen[k].topic);
          readers_seen[k] = readers_seen[--nreaders_seen];
          break;
        }
        continue;
      }
      if (!infos[i].valid_data || r->topic_name == NULL) continue;
      if (memcmp(r->participant_key.v, me->v, 12) == 0) continue;
      if (nreaders_seen == readers_cap) {
        readers_cap = readers_cap ? 2 * readers_cap : 256;
        readers_seen = realloc(readers_seen, readers_cap * sizeof *readers_seen);
      }
      struct seen_reader* s = &readers_seen[nreaders_seen++];
      s->instance = infos[i].instance_handle;
      guid_hex(&r->participant_key, s->participant);
      s->topic = strdup(r->topic_name);
      printf("count_probe: reader+ %s %s\n", s->participant, s->topic);
    }
    if (n > 0) {
      dds_return_loan(subscriptions, samples, n);
      fflush(stdout);
    }
    if (n < BATCH) return;
  }
}

static int in_partition(const dds_qos_t* qos, const char* partition) {
  uint32_t n = 0;
  char** ps = NULL;
  int found = 0;
  if (dds_qget_partition(qos, &n, &ps)) {
    for (uint32_t i = 0; i < n; i++) {
      if (strcmp(ps[i], partition) == 0) found = 1;
      dds_free(ps[i]);
    }
    dds_free(ps);
  }
  return found;
}

/* A reader for a writer's topic not yet read, of the type its writer announced. */
static void subscribe(dds_entity_t pp, dds_entity_t sub, dds_entity_t waitset,
                      dds_builtintopic_endpoint_t* w, int cameras) {
  if (ntopics == MAX_TOPICS || find(w->topic_name) != NULL) return;
  if (!cameras && strstr(w->type_name, "sensor_msgs::msg::dds_::Image_") != NULL) return;
  if (nonly > 0) {
    int wanted = 0;
    for (int i = 0; i < nonly; i++) wanted |= strcmp(only[i], w->topic_name) == 0;
    if (!wanted) return;
  }
  const dds_topic_descriptor_t* descriptor = descriptor_of(w->type_name);
  if (descriptor == NULL) {
    fprintf(stderr, "count_probe: %s: type %s is not among the probe's types\n", w->topic_name,
            w->type_name);
    failures++;
    return;
  }
  const dds_entity_t topic = dds_create_topic(pp, descriptor, w->topic_name, NULL, NULL);
  if (topic < 0) {
    fprintf(stderr, "count_probe: %s: dds_create_topic: %s\n", w->topic_name,
            dds_strretcode(topic));
    failures++;
    return;
  }
  dds_reliability_kind_t reliability = DDS_RELIABILITY_RELIABLE;
  dds_duration_t blocking = 0;
  (void)dds_qget_reliability(w->qos, &reliability, &blocking);
  dds_qos_t* rq = dds_create_qos();
  dds_qset_reliability(rq, reliability, DDS_SECS(1));
  dds_qset_durability(rq, DDS_DURABILITY_VOLATILE);
  dds_qset_history(rq, DDS_HISTORY_KEEP_ALL, 0);
  const dds_entity_t reader = dds_create_reader(sub, topic, rq, NULL);
  dds_delete_qos(rq);
  if (reader < 0) {
    fprintf(stderr, "count_probe: %s: dds_create_reader: %s\n", w->topic_name,
            dds_strretcode(reader));
    failures++;
    return;
  }
  struct topic* t = &topics[ntopics++];
  t->name = strdup(w->topic_name);
  t->type = strdup(w->type_name);
  t->reliable = reliability == DDS_RELIABILITY_RELIABLE;
  t->reader = reader;
  t->since = dds_time();
  for (int i = 0; i < npayload_topics; i++) {
    t->keep_payloads |= strcmp(payload_topics[i], w->topic_name) == 0;
  }
  dds_waitset_attach(waitset, dds_create_readcondition(reader, DDS_ANY_STATE), 0);
}

static void take(struct topic* t) {
  for (;;) {
    struct ddsi_serdata* data[BATCH];
    dds_sample_info_t infos[BATCH];
    const dds_return_t n = dds_takecdr(t->reader, data, BATCH, infos, DDS_ANY_STATE);
    if (n <= 0) return;
    for (dds_return_t i = 0; i < n; i++) {
      if (infos[i].valid_data) {
        if (t->n == t->cap) {
          t->cap = t->cap ? 2 * t->cap : 1024;
          t->stamps = realloc(t->stamps, t->cap * sizeof *t->stamps);
          if (t->keep_payloads) t->payloads = realloc(t->payloads, t->cap * sizeof *t->payloads);
        }
        if (t->keep_payloads) {
          const uint32_t size = ddsi_serdata_size(data[i]);
          unsigned char* bytes = malloc(size);
          char* hex = malloc(2 * (size_t)size + 1);
          ddsi_serdata_to_ser(data[i], 0, size, bytes);
          for (uint32_t k = 0; k < size; k++) sprintf(hex + 2 * k, "%02x", bytes[k]);
          hex[2 * (size_t)size] = '\0';
          free(bytes);
          t->payloads[t->n] = hex;
        }
        t->stamps[t->n++] = infos[i].source_timestamp;
      }
      ddsi_serdata_unref(data[i]);
    }
  }
}

int main(int argc, char** argv) {
  int cameras = 0;
  int watch = 0;
  int list = 0;
  int bad = argc < 4;
  for (int i = 4; i < argc && !bad; i++) {
    if (strcmp(argv[i], "--cameras") == 0) {
      cameras = 1;
    } else if (strcmp(argv[i], "--only") == 0 && i + 1 < argc && nonly < 64) {
      only[nonly++] = argv[++i];
    } else if (strcmp(argv[i], "--payloads") == 0 && i + 1 < argc && npayload_topics < 64) {
      payload_topics[npayload_topics++] = argv[++i];
    } else if (strcmp(argv[i], "--watch-readers") == 0) {
      watch = 1;
    } else if (strcmp(argv[i], "--list-topics") == 0) {
      list = 1;
    } else {
      bad = 1;
    }
  }
  if (bad) {
    fprintf(stderr,
            "usage: %s PARTITION SECONDS OUT [--cameras] [--only DDS_TOPIC]... "
            "[--payloads DDS_TOPIC]... [--watch-readers] [--list-topics]\n",
            argv[0]);
    return 2;
  }
  const char* partition = argv[1];
  const double seconds = atof(argv[2]);
  const dds_entity_t pp = dds_create_participant(DDS_DOMAIN_DEFAULT, NULL, NULL);
  if (pp < 0) {
    fprintf(stderr, "count_probe: dds_create_participant: %s\n", dds_strretcode(pp));
    return 1;
  }
  dds_guid_t me;
  dds_get_guid(pp, &me);
  const dds_entity_t publications =
      dds_create_reader(pp, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, NULL, NULL);
  dds_qos_t* sq = dds_create_qos();
  dds_qset_partition1(sq, partition);
  const dds_entity_t sub = dds_create_subscriber(pp, sq, NULL);
  dds_delete_qos(sq);
  const dds_entity_t waitset = dds_create_waitset(pp);
  if (publications < 0 || sub < 0 || waitset < 0) {
    fprintf(stderr, "count_probe: could not create the readers\n");
    return 1;
  }
  dds_waitset_attach(waitset, dds_create_readcondition(publications, DDS_ANY_STATE), 0);
  dds_entity_t subscriptions = 0;
  if (watch) {
    subscriptions = dds_create_reader(pp, DDS_BUILTIN_TOPIC_DCPSSUBSCRIPTION, NULL, NULL);
    if (subscriptions < 0) {
      fprintf(stderr, "count_probe: could not read DCPSSubscription\n");
      return 1;
    }
    dds_waitset_attach(waitset, dds_create_readcondition(subscriptions, DDS_ANY_STATE), 0);
  }
  signal(SIGINT, on_signal);
  signal(SIGTERM, on_signal);
  const dds_time_t end = dds_time() + (dds_duration_t)(seconds * 1e9);
  dds_time_t last_new = 0;
  int ready = 0;
  while (!stop && dds_time() < end) {
    const size_t known = ntopics;
    void* samples[BATCH] = {0};
    dds_sample_info_t infos[BATCH];
    const dds_return_t n = dds_take(publications, samples, infos, BATCH, BATCH);
    for (dds_return_t i = 0; i < n; i++) {
      dds_builtintopic_endpoint_t* w = samples[i];
      /* Alive writers of the city's partition, not our own participant's. */
      if (!infos[i].valid_data || infos[i].instance_state != DDS_IST_ALIVE) continue;
      if (memcmp(w->participant_key.v, me.v, 12) == 0) continue;
      if (!in_partition(w->qos, partition)) continue;
      if (list) list_topic(w);
      subscribe(pp, sub, waitset, w, cameras);
    }
    if (n > 0) dds_return_loan(publications, samples, n);
    for (size_t i = 0; i < ntopics; i++) take(&topics[i]);
    if (watch) watch_readers(subscriptions, &me);
    const dds_time_t now = dds_time();
    if (ntopics != known) last_new = now;
    if (!ready && ntopics > 0 && now - last_new >= DDS_SECS(1)) {
      printf("count_probe: reading %zu topics in partition %s\n", ntopics, partition);
      fflush(stdout);
      ready = 1;
    }
    /* Short waits: a signal or the quiet second is noticed soon. */
    const dds_time_t until = now + DDS_MSECS(100) < end ? now + DDS_MSECS(100) : end;
    dds_waitset_wait_until(waitset, NULL, 0, until);
  }
  for (size_t i = 0; i < ntopics; i++) take(&topics[i]);
  FILE* out = fopen(argv[3], "w");
  if (out == NULL) {
    perror(argv[3]);
    return 1;
  }
  for (size_t i = 0; i < ntopics; i++) {
    const struct topic* t = &topics[i];
    dds_sample_lost_status_t lost = {0};
    (void)dds_get_sample_lost_status(t->reader, &lost);
    fprintf(out,
            "{\"topic\":\"%s\",\"type\":\"%s\",\"reliable\":%s,\"since\":%lld,\"lost\":%u,"
            "\"stamps\":[",
            t->name, t->type, t->reliable ? "true" : "false", (long long)t->since,
            lost.total_count);
    for (size_t k = 0; k < t->n; k++) fprintf(out, "%s%lld", k ? "," : "", (long long)t->stamps[k]);
    fprintf(out, "]");
    if (t->keep_payloads) {
      fprintf(out, ",\"payloads\":[");
      for (size_t k = 0; k < t->n; k++) fprintf(out, "%s\"%s\"", k ? "," : "", t->payloads[k]);
      fprintf(out, "]");
    }
    fprintf(out, "}\n");
    printf("count_probe: %-50s %8zu samples\n", t->name, t->n);
  }
  fclose(out);
  dds_delete(pp);
  return failures ? 1 : 0;
}
